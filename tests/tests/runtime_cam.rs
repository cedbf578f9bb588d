//! Cam tables while the cycle runs, through the [`Controller`] and the engine on the
//! in-process simulator in lockstep: the configuration's table is in its slot at start;
//! a table loaded at runtime takes the first free slot between two cycles, one loaded
//! under a known name replaces its table; while an axis cams on a table it can be neither
//! replaced nor removed (refused naming table and axis, the kernel's table untouched);
//! after CamOut it can. The kernel's slots are read after each step, so what the
//! controller reports is checked against what the cycle runs.

use gantry::cam::cam_from_points;
use gantry::runtime::controller::{CamHandle, ControlError, Controller};
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::cam::{CamTable, Interpolation};
use gantry_kernel::kernel::CAM_SLOTS;
use gantry_kernel::sync::command::CamIn;
use gantry_tests::rig::Rig;
use gantry_tests::{sim_config_text, DEFAULT_SYNC_ERROR_LIMIT};

const S: usize = 1;
const V: usize = 2;

fn config() -> gantry::config::Config {
    let slaves = format!(
        "[[slave]]\nkind = \"servo\"\n[slave.al]\nsync_error_limit = {DEFAULT_SYNC_ERROR_LIMIT}\n"
    );
    let max = "max = { speed = 20.0, acceleration = 200.0, jerk = 4000.0 }\n";
    let press = concat!(env!("CARGO_MANIFEST_DIR"), "/../deploy/cams/eccentric.toml");
    let axes = format!(
        "[[axis]]\nname = \"x\"\ndrive = 0\nhoming_required = false\n\
         scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n{max}\
         [[axis]]\nname = \"s\"\ntype = \"simulated\"\nhoming_required = false\n{max}\
         [[axis]]\nname = \"v\"\ntype = \"virtual\"\n{max}\
         [[cam]]\nname = \"press\"\nfile = {press:?}\n"
    );
    sim_config_text(1000, &slaves, "", &axes)
}

/// A linear table of `n` points from (0, 0) to (100, 10).
fn ramp(n: usize) -> CamTable {
    let points: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let x = 100.0 * i as f64 / (n - 1) as f64;
            [x, x / 10.0]
        })
        .collect();
    cam_from_points(&points, Some(Interpolation::Linear), None).unwrap()
}

/// Cycles until `h` has ended; its outcome. The load is not done before a cycle ran.
fn outcome(rig: &mut Rig, h: &CamHandle) -> Result<usize, ControlError> {
    assert!(h.outcome().is_none(), "no cycle ran: nothing is done yet");
    for _ in 0..10 {
        rig.cycle();
        if let Some(r) = h.outcome() {
            return r;
        }
    }
    panic!("no outcome in 10 cycles");
}

/// Points of the table the kernel holds in `slot`.
fn kernel_points(rig: &Rig, slot: usize) -> Option<usize> {
    rig.engine
        .cycle
        .kernel
        .cam_table(slot)
        .map(|t| t.points().len())
}

fn points_of(ctl: &Controller, name: &str) -> Option<usize> {
    ctl.cam_tables()
        .into_iter()
        .find(|c| c.name == name)
        .map(|c| c.points)
}

#[test]
fn cam_tables_load_replace_are_refused_while_an_axis_cams_on_them_and_fill_every_slot() {
    let mut rig = Rig::new(&config());
    let ctl = rig.ctl.clone();
    rig.run(5);

    // The configuration's table, in slot 0.
    let tables = ctl.cam_tables();
    assert_eq!(tables.len(), 1, "{tables:?}");
    let press = &tables[0];
    assert_eq!((press.name.as_str(), press.slot), ("press", 0));
    assert_eq!(press.points, 13);
    assert_eq!(press.interpolation, Interpolation::Cubic);
    assert!(press.periodic);
    assert_eq!(press.master_range, (0.0, 360.0));
    assert_eq!(press.slave_rise, 0.0);
    assert_eq!(ctl.cam_slot("press"), Some(0));
    assert_eq!(kernel_points(&rig, 0), Some(13));

    // A new name takes the first free slot, between two cycles.
    let h = ctl.load_cam("knife", ramp(3)).unwrap();
    assert_eq!(
        ctl.cam_slot("knife"),
        None,
        "not loaded before the cycle took it"
    );
    assert_eq!(outcome(&mut rig, &h), Ok(1));
    assert_eq!(ctl.cam_slot("knife"), Some(1));
    assert_eq!(kernel_points(&rig, 1), Some(3));
    // A known name: its table replaced, in its slot.
    let h = ctl.load_cam("knife", ramp(5)).unwrap();
    assert_eq!(outcome(&mut rig, &h), Ok(1));
    assert_eq!(kernel_points(&rig, 1), Some(5));
    assert_eq!(points_of(&ctl, "knife"), Some(5));
    assert_eq!(ctl.cam_tables().len(), 2);

    // s cams on knife, following the virtual axis v.
    for axis in [S, V] {
        assert_eq!(
            rig.command(axis, Command::Power(PowerCommand::Enable)),
            CommandStatus::Done
        );
    }
    let cam_in = ctl
        .command(S, Command::CamIn(CamIn::new(V, 1, true)))
        .unwrap();
    // The status is published every few cycles.
    rig.run(20);
    assert_eq!(cam_in.status(), Some(CommandStatus::Active));
    assert!(rig.engine.cycle.kernel.axes()[S].cam_table_in_use() == Some(1));

    // Neither replaced nor removed while it is in use; the kernel keeps its table.
    let h = ctl.load_cam("knife", ramp(7)).unwrap();
    let refused = outcome(&mut rig, &h).unwrap_err();
    assert_eq!(
        refused,
        ControlError::CamInUse {
            name: "knife".into(),
            axis: "s".into()
        }
    );
    assert_eq!(
        refused.to_string(),
        "cam table knife is in use by axis s; CamOut first"
    );
    let h = ctl.remove_cam("knife").unwrap();
    assert!(matches!(
        outcome(&mut rig, &h),
        Err(ControlError::CamInUse { .. })
    ));
    assert_eq!(kernel_points(&rig, 1), Some(5));
    assert_eq!(points_of(&ctl, "knife"), Some(5));
    assert_eq!(ctl.cam_slot("knife"), Some(1));
    // Another table is free to change meanwhile.
    let h = ctl.load_cam("press", ramp(4)).unwrap();
    assert_eq!(outcome(&mut rig, &h), Ok(0));
    assert_eq!(kernel_points(&rig, 0), Some(4));
    assert_eq!(points_of(&ctl, "press"), Some(4));

    // After CamOut: replaced, then removed; its slot is the next new name's.
    let out = ctl.command(S, Command::CamOut).unwrap();
    assert_eq!(rig.finish(&out, 10), CommandStatus::Done);
    let h = ctl.load_cam("knife", ramp(7)).unwrap();
    assert_eq!(outcome(&mut rig, &h), Ok(1));
    assert_eq!(kernel_points(&rig, 1), Some(7));
    let h = ctl.remove_cam("knife").unwrap();
    assert_eq!(outcome(&mut rig, &h), Ok(1));
    assert_eq!(kernel_points(&rig, 1), None);
    assert_eq!(ctl.cam_slot("knife"), None);
    assert_eq!(ctl.cam_tables().len(), 1);
    let h = ctl.load_cam("knife2", ramp(2)).unwrap();
    assert_eq!(outcome(&mut rig, &h), Ok(1));

    // Refused at once.
    assert_eq!(
        ctl.remove_cam("nothing").unwrap_err(),
        ControlError::NoCam("nothing".into())
    );
    assert_eq!(
        ctl.load_cam(" ", ramp(2)).unwrap_err(),
        ControlError::CamUnnamed
    );

    // Every slot filled (loads queue up; the cycle takes one a cycle): a new name is
    // refused at once, a known one is still replaced.
    let handles: Vec<_> = (2..CAM_SLOTS)
        .map(|i| {
            let h = ctl.load_cam(&format!("t{i}"), ramp(2));
            if i % 4 == 0 {
                rig.run(4);
            }
            h.unwrap()
        })
        .collect();
    rig.run(CAM_SLOTS + 2);
    for (i, h) in handles.iter().enumerate() {
        assert_eq!(h.outcome(), Some(Ok(i + 2)));
    }
    assert_eq!(ctl.cam_tables().len(), CAM_SLOTS);
    let e = ctl.load_cam("one more", ramp(2)).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "no free cam slot for \"one more\": all {CAM_SLOTS} hold tables (remove one, or \
             replace a table by loading it under its name)"
        )
    );
    // Replacing is still possible.
    let h = ctl.load_cam("t3", ramp(3)).unwrap();
    rig.run(2);
    assert_eq!(h.outcome(), Some(Ok(3)));
}
