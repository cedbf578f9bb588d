//! Camming (PLCopen MC_CamIn, MC_CamOut) in lockstep: the follower on the table across
//! modulo wraps of master and follower with periods unrelated to the table's, no jump at
//! engage or disengage, EndOfProfile, and the refusals.

mod common;

use common::sync::*;
use common::*;
use gantry_kernel::axis::command::{Command, CommandError};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::cam::{CamPoint, CamTable, Interpolation};
use gantry_kernel::kernel::CamSlotError;
use gantry_kernel::mechanics::Modulo;
use gantry_kernel::sync::command::{CamIn, CamStart};

/// A table over 250 master units rising 40 each period, through five points.
fn rising(interpolation: Interpolation, periodic: bool) -> CamTable {
    let pts = [
        (0.0, 0.0),
        (50.0, 10.0),
        (125.0, 30.0),
        (200.0, 35.0),
        (250.0, 40.0),
    ];
    CamTable::new(
        pts.iter()
            .map(|&(master, slave)| CamPoint { master, slave })
            .collect(),
        interpolation,
        periodic,
    )
    .unwrap()
}

/// The table unrolled over its periods, evaluated independently of the kernel's law.
fn unrolled(t: &CamTable, x: f64) -> f64 {
    let (x0, x1) = t.master_range();
    let len = x1 - x0;
    let c = ((x - x0) / len).floor();
    t.eval(x - c * len).slave + c * t.slave_rise()
}

#[test]
fn a_periodic_cam_follows_the_table_across_unrelated_modulo_wraps() {
    for interpolation in [
        Interpolation::Linear,
        Interpolation::Cubic,
        Interpolation::Quintic,
    ] {
        let mut m = virtual_master();
        m.mechanics.modulo = Modulo::new(360.0);
        let mut f = follower("f");
        f.mechanics.modulo = Modulo::new(100.0);
        let mut k = kernel(vec![m, f]);
        let table = rising(interpolation, true);
        k.set_cam_table(3, Some(table.clone())).unwrap();
        let h = k
            .command(1, Command::CamIn(CamIn::new(0, 3, true)))
            .unwrap();
        k.command(0, velocity(100.0)).unwrap();
        let trace = steps(&mut k, 12_000); // 1200° of master: 4.8 table periods
        let f: Vec<_> = trace.iter().map(|t| t.1).collect();
        if interpolation != Interpolation::Linear {
            // A linear table has corners: its velocity steps there (by design).
            assert_smooth(&f, Some(100.0), 1000.0, 10_000.0, interpolation.name());
        }
        let mut pulses = 0;
        for (ms, fs) in &trace {
            let x = ms.turns as f64 * 360.0 + ms.set.p;
            let want = unrolled(&table, x);
            let got = fs.turns as f64 * 100.0 + fs.set.p;
            assert!(
                (got - want).abs() < 1e-9,
                "{interpolation:?}: master {x}: follower {got}, table {want}"
            );
            assert!(fs.bits.camming && fs.bits.in_sync);
            pulses += usize::from(fs.bits.end_of_profile);
        }
        // Table periods begun: at 250, 500, 750 and 1000 master units.
        assert_eq!(pulses, 4, "{interpolation:?}");
        assert!(f.last().unwrap().turns >= 1, "the follower wrapped");
        assert_eq!(k.command_status(h), CommandStatus::Active);
        // The table is in use: it cannot be replaced until CamOut.
        assert!(matches!(
            k.set_cam_table(3, None),
            Err(CamSlotError::InUse { slot: 3, axis: 1 })
        ));
        let out = k.command(1, Command::CamOut).unwrap();
        assert_eq!(k.command_status(out), CommandStatus::Done);
        assert_eq!(k.command_status(h), CommandStatus::Done);
        let after = steps(&mut k, 100);
        assert!(after
            .iter()
            .all(|(_, s)| s.state == AxisState::ContinuousMotion && !s.bits.camming));
        assert!(k.set_cam_table(3, None).unwrap().is_some());
    }
}

#[test]
fn an_absolute_cam_catches_up_onto_the_table_without_a_jump() {
    let mut m = virtual_master();
    m.mechanics.modulo = Modulo::new(360.0);
    let f = follower("f");
    let mut k = kernel(vec![m, f]);
    let table = rising(Interpolation::Cubic, true);
    k.set_cam_table(0, Some(table.clone())).unwrap();
    k.command(0, velocity(90.0)).unwrap();
    steps(&mut k, 2000);
    // The follower stands 25 units away from where the table wants it.
    let mut cam = CamIn::new(0, 0, true);
    cam.slave_offset = -25.0;
    cam.master_scaling = 0.5;
    cam.slave_scaling = 2.0;
    k.command(1, Command::CamIn(cam)).unwrap();
    let trace = steps(&mut k, 6000);
    let f: Vec<_> = trace.iter().map(|t| t.1).collect();
    assert_smooth(&f, None, 1000.0, 30_000.0, "absolute CamIn");
    let sync = f.iter().position(|s| s.bits.in_sync).expect("in sync");
    assert!(sync > 10, "it took time to catch up");
    let x_at = |ms: &gantry_kernel::axis::status::AxisStatus| ms.turns as f64 * 360.0 + ms.set.p;
    // On the table from there on: f = −25 + 2 · T(0.5 · master), the master counted from
    // where the cam began (its position then, in its period, is the table's reference).
    let begin_turns = trace[0].0.turns;
    for (ms, fs) in &trace[sync..] {
        let x = 0.5 * (x_at(ms) - begin_turns as f64 * 360.0);
        let want = -25.0 + 2.0 * unrolled(&table, x);
        assert!((fs.set.p - want).abs() < 1e-9, "{} vs {want}", fs.set.p);
    }
}

#[test]
fn a_non_periodic_cam_ends_with_end_of_profile_and_goes_on_at_its_velocity() {
    let mut k = kernel(vec![virtual_master(), follower("f")]);
    // Ends rising at slope 50/60 (not at rest): the follower then keeps that times the
    // master's speed.
    let table = CamTable::new(
        [(0.0, 0.0), (40.0, 10.0), (100.0, 60.0)]
            .iter()
            .map(|&(master, slave)| CamPoint { master, slave })
            .collect(),
        Interpolation::Linear,
        false,
    )
    .unwrap();
    k.set_cam_table(1, Some(table)).unwrap();
    let h = k
        .command(1, Command::CamIn(CamIn::new(0, 1, false)))
        .unwrap();
    k.command(0, velocity(50.0)).unwrap();
    let trace = steps(&mut k, 4000);
    let end = trace
        .iter()
        .position(|(_, s)| s.bits.end_of_profile)
        .expect("EndOfProfile");
    assert!((trace[end].0.set.p - 100.0).abs() <= 50.0 * DT * 1.01);
    assert_eq!(k.command_status(h), CommandStatus::Done);
    let after = &trace[end + 1..];
    assert!(after
        .iter()
        .all(|(_, s)| s.state == AxisState::ContinuousMotion && !s.bits.camming));
    let v_end = after.last().unwrap().1.set.v;
    assert!(
        (v_end - 50.0 / 60.0 * 50.0).abs() < 1e-9,
        "{v_end} {:?}",
        &after[..3]
    );
    let f: Vec<_> = trace[end - 50..].iter().map(|t| t.1).collect();
    assert_smooth(&f, None, 1000.0, 1e9, "end of profile");
}

#[test]
fn a_relative_cam_starts_at_the_table_start_where_the_follower_is() {
    let mut k = kernel(vec![virtual_master(), follower("f")]);
    let table = rising(Interpolation::Cubic, true);
    k.set_cam_table(0, Some(table.clone())).unwrap();
    k.command(1, velocity(5.0)).unwrap();
    k.command(0, velocity(50.0)).unwrap();
    steps(&mut k, 1000);
    let mut cam = CamIn::new(0, 0, true);
    cam.start = CamStart::Relative;
    k.command(1, Command::CamIn(cam)).unwrap();
    let trace = steps(&mut k, 4000);
    let f: Vec<_> = trace.iter().map(|t| t.1).collect();
    assert_smooth(&f, None, 1000.0, 30_000.0, "relative CamIn");
    // After catching up the follower is the table plus a constant (what the catch-up left).
    let sync = f.iter().position(|s| s.bits.in_sync).expect("in sync");
    let m0 = trace[0].0.set.p - 0.05; // the master where the cam began (one cycle earlier)
    let offsets: Vec<f64> = trace[sync..]
        .iter()
        .map(|(ms, fs)| fs.set.p - unrolled(&table, ms.set.p - m0))
        .collect();
    let (lo, hi) = offsets
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &o| (a.min(o), b.max(o)));
    assert!(hi - lo < 1e-9, "offset varies by {}", hi - lo);
}

#[test]
fn cam_refusals_name_the_problem() {
    let mut k = kernel(vec![virtual_master(), follower("f")]);
    let e = k
        .command(1, Command::CamIn(CamIn::new(0, 5, true)))
        .unwrap_err();
    assert_eq!(
        e,
        CommandError::NoSuchCamTable {
            command: "CamIn",
            table: 5
        }
    );
    assert!(e.to_string().contains("no cam table in slot 5"));
    let table = rising(Interpolation::Linear, false);
    k.set_cam_table(5, Some(table)).unwrap();
    let mut cam = CamIn::new(0, 5, true);
    cam.master_scaling = 0.0;
    let e = k.command(1, Command::CamIn(cam)).unwrap_err();
    assert!(e.to_string().contains("scaling"), "{e}");
    // A non-periodic table the master is not on.
    let mut cam = CamIn::new(0, 5, false);
    cam.master_offset = 300.0;
    let e = k.command(1, Command::CamIn(cam)).unwrap_err();
    assert!(
        e.to_string().contains("outside the non-periodic table"),
        "{e}"
    );
    assert!(matches!(
        k.set_cam_table(99, None),
        Err(CamSlotError::NoSuchSlot { slot: 99 })
    ));
    let e = k.command(1, Command::GearOut).unwrap_err();
    assert!(matches!(e, CommandError::NotAllowedInState { .. }), "{e}");
}
