//! A cam table load, and gearing and camming themselves, neither allocate nor free in the
//! cycle thread, in the configuration `gantry run` uses (`service::start_cycle`:
//! SCHED_FIFO, memory locked, `Engine::run`): while a counting allocator watches the
//! cycle thread from its first cycle to its last, the application loads tables (new names
//! and replacements of the configuration's), the virtual master moves, the servo axis
//! gears to it and the simulated axis cams on one of the tables while it does, a
//! replacement of that table is refused (the new table comes back to the application),
//! both axes gear and cam out, and a table is removed. Each table the cycle
//! thread puts into a slot is allocated by the application and each one it takes out is
//! handed back to it, so the counts are 0 and 0. Needs root (real time), as
//! `deploy/test.sh` runs it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Duration;

use gantry::cam::cam_from_points;
use gantry::runtime::controller::{ControlError, Controller};
use gantry::service::{start_cycle, CYCLE_STACK_BYTES, CYCLE_THREAD};
use gantry_cli::simulator::{SimLink, Simulator};
use gantry_kernel::axis::command::{Command, PowerCommand};
use gantry_kernel::axis::command::{MoveDirection, MoveVelocity};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::cam::{CamTable, Interpolation};
use gantry_kernel::sync::command::{CamIn, GearIn};

mod counting {
    include!("../../kernel/tests/common/counting_alloc.rs");
}

#[global_allocator]
static ALLOC: counting::Counting = counting::Counting;

const X: usize = 0;
const S: usize = 1;
const V: usize = 2;

fn ramp(n: usize, interpolation: Interpolation) -> CamTable {
    let points: Vec<[f64; 2]> = (0..n).map(|i| [i as f64 * 10.0, i as f64]).collect();
    cam_from_points(&points, Some(interpolation), None).unwrap()
}

#[test]
fn a_cam_load_in_flight_neither_allocates_nor_frees_in_the_cycle_thread() {
    let slaves = "[[slave]]\nkind = \"servo\"\n[slave.al]\nsync_error_limit = 40\n";
    let max = "max = { speed = 20.0, acceleration = 200.0, jerk = 4000.0 }\n";
    let press = concat!(env!("CARGO_MANIFEST_DIR"), "/../deploy/cams/eccentric.toml");
    let axes = format!(
        "[[axis]]\nname = \"x\"\ndrive = 0\nhoming_required = false\n\
         scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n{max}\
         [[axis]]\nname = \"s\"\ntype = \"simulated\"\nhoming_required = false\n{max}\
         [[axis]]\nname = \"v\"\ntype = \"virtual\"\n{max}\
         [[cam]]\nname = \"press\"\nfile = {press:?}\n"
    );
    let mut config = gantry_tests::sim_config_text(1000, slaves, "", &axes);
    config.bus.faults.lost_frames_limit = 50;
    gantry::runtime::rt::check(&config.rt, false).expect("this test needs root (SCHED_FIFO)");
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    let cycle_stop = stop.clone();
    let cycle_thread = std::thread::Builder::new()
        .name(CYCLE_THREAD.into())
        .stack_size(CYCLE_STACK_BYTES)
        .spawn(move || {
            let simulator = Simulator::new(SimLink::Thread);
            let (engine, ends) =
                start_cycle(&config, true, &simulator, &mut std::io::sink()).unwrap();
            tx.send(ends).unwrap();
            // The counters count: an allocation and a free while watching are seen.
            counting::watch(true);
            drop(std::hint::black_box(vec![1u8; 16]));
            counting::watch(false);
            assert_eq!(counting::take_count(), 1, "the counting allocator works");
            assert_eq!(counting::take_frees(), 1, "the counting allocator works");
            counting::watch(true);
            let engine = engine.run(1_000_000, &cycle_stop);
            counting::watch(false);
            let counts = (counting::take_count(), counting::take_frees());
            (counts, engine.counters().cycles)
        })
        .unwrap();
    let ends = rx.recv().unwrap();
    let ctl = Controller::new(ends, vec!["x".into(), "s".into(), "v".into()]);
    let wait = Duration::from_secs(5);
    let mut loads = 0;
    for round in 0..20 {
        let interpolation = [
            Interpolation::Linear,
            Interpolation::Cubic,
            Interpolation::Quintic,
        ][round % 3];
        // A new name, then replacements of it and of the configuration's table.
        let h = ctl
            .load_cam("knife", ramp(3 + round * 50, interpolation))
            .unwrap();
        assert_eq!(h.wait(wait), Ok(1));
        let h = ctl
            .load_cam("press", ramp(2 + round, interpolation))
            .unwrap();
        assert_eq!(h.wait(wait), Ok(0));
        loads += 2;
    }
    // Refused while s cams on knife: the refused table comes back to be dropped here.
    for axis in [X, S, V] {
        let h = ctl
            .command(axis, Command::Power(PowerCommand::Enable))
            .unwrap();
        assert_eq!(h.wait(wait), Ok(CommandStatus::Done));
    }
    let gear_in = ctl
        .command(X, Command::GearIn(GearIn::new(V, 1, 2)))
        .unwrap();
    let cam_in = ctl
        .command(S, Command::CamIn(CamIn::new(V, 1, true)))
        .unwrap();
    ctl.command(
        V,
        Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 10.0)),
    )
    .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(gear_in.status(), Some(CommandStatus::Active));
    assert_eq!(cam_in.status(), Some(CommandStatus::Active));
    let snap = ctl.snapshot();
    for axis in [X, S] {
        let a = &snap.axes[axis];
        assert!(a.bits.in_sync && a.set.v.abs() > 0.1, "axis {axis}: {a:?}");
    }
    for _ in 0..5 {
        let h = ctl
            .load_cam("knife", ramp(1000, Interpolation::Cubic))
            .unwrap();
        assert!(matches!(h.wait(wait), Err(ControlError::CamInUse { .. })));
        loads += 1;
    }
    let out = ctl.command(S, Command::CamOut).unwrap();
    assert_eq!(out.wait(wait), Ok(CommandStatus::Done));
    let out = ctl.command(X, Command::GearOut).unwrap();
    assert_eq!(out.wait(wait), Ok(CommandStatus::Done));
    let h = ctl.remove_cam("knife").unwrap();
    assert_eq!(h.wait(wait), Ok(1));
    assert_eq!(ctl.cam_tables().len(), 1);
    stop.store(true, Ordering::Relaxed);
    let ((allocations, frees), cycles) = cycle_thread.join().unwrap();
    eprintln!(
        "cycle thread: {allocations} allocations, {frees} frees in {cycles} cycles; {loads} \
         cam loads"
    );
    assert!(
        loads >= 45 && cycles > 40,
        "{loads} loads in {cycles} cycles"
    );
    assert_eq!(allocations, 0);
    assert_eq!(frees, 0);
}
