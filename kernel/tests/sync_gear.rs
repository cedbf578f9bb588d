//! Gearing (PLCopen MC_GearIn, MC_GearInPos, MC_GearOut) in lockstep: no jump at engage or
//! disengage, the follower exactly on the gear over long runs, the follower's limits, and
//! what followers do when their master fails.

mod common;

use common::sync::*;
use common::*;
use gantry_kernel::axis::command::{Command, CommandError, MovePtp, PositioningMode};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::{AxisFault, AxisStatus};
use gantry_kernel::axis::{AxisFeedback, SyncLimitReaction};
use gantry_kernel::mechanics::Modulo;
use gantry_kernel::sync::command::{CatchUp, GearIn, GearInPos};
use gantry_kernel::{AxisConfig, AxisKind, Kernel};

#[test]
fn gear_in_catches_up_without_a_jump_and_then_holds_the_ratio_exactly() {
    let mut k = kernel(vec![virtual_master(), follower("f")]);
    k.command(0, velocity(100.0)).unwrap();
    steps(&mut k, 700); // the master at speed
                        // The follower moves on its own first: gearing in takes over from a moving axis.
    k.command(1, velocity(-20.0)).unwrap();
    steps(&mut k, 100);
    let h = k.command(1, Command::GearIn(GearIn::new(0, 3, 2))).unwrap();
    assert_eq!(k.command_status(h), CommandStatus::Active);
    let trace = steps(&mut k, 2000);
    let f: Vec<_> = trace.iter().map(|t| t.1).collect();
    assert_smooth(&f, None, 500.0 * 1.001 + 1.5 * 1000.0, 1e9, "GearIn engage");
    let in_gear = f
        .iter()
        .position(|s| s.bits.in_sync)
        .expect("InGear within 2 s");
    assert!(f[..in_gear].iter().all(|s| !s.bits.in_sync));
    assert!(f
        .iter()
        .all(|s| s.state == AxisState::SynchronizedMotion && s.bits.gearing));
    assert_eq!(f[0].master, Some(0));
    // From InGear on, follower travel = 3/2 master travel, to rounding.
    let (m0, f0) = (trace[in_gear].0.set.p, trace[in_gear].1.set.p);
    let worst = trace[in_gear..]
        .iter()
        .map(|(m, f)| ((f.set.p - f0) - 1.5 * (m.set.p - m0)).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "gear error {worst}");
    assert!((f.last().unwrap().set.v - 150.0).abs() < 1e-9);
    // The master changes speed: the follower follows at the ratio, still in gear.
    k.command(0, velocity(40.0)).unwrap();
    let trace = steps(&mut k, 1500);
    for (m, fs) in &trace {
        assert!((fs.set.v - 1.5 * m.set.v).abs() < 1e-9);
        assert!(fs.bits.in_sync);
    }
    assert_eq!(k.command_status(h), CommandStatus::Active);
}

#[test]
fn gear_out_goes_on_at_the_velocity_and_a_move_takes_over_without_a_jump() {
    let mut k = kernel(vec![virtual_master(), follower("f")]);
    k.command(0, velocity(100.0)).unwrap();
    let gear = k
        .command(1, Command::GearIn(GearIn::new(0, -1, 2)))
        .unwrap();
    let before = steps(&mut k, 1500);
    assert!(
        before.iter().all(|(_, s)| s.bits.gearing),
        "{:?}",
        before.last()
    );
    let out = k.command(1, Command::GearOut).unwrap();
    assert_eq!(k.command_status(out), CommandStatus::Done);
    assert_eq!(k.command_status(gear), CommandStatus::Done);
    let after = steps(&mut k, 500);
    let f: Vec<_> = before.iter().chain(&after).map(|t| t.1).collect();
    assert_smooth(&f, None, 1000.0, 1e9, "GearOut");
    assert!(after
        .iter()
        .all(|(_, s)| s.state == AxisState::ContinuousMotion && !s.bits.gearing));
    assert!((after.last().unwrap().1.set.v + 50.0).abs() < 1e-9);
    // GearOut again: the axis is not gearing any more.
    assert!(matches!(
        k.command(1, Command::GearOut),
        Err(CommandError::NotAllowedInState { .. })
    ));
    // Gear in again, then a positioning move aborts the gear from its set values.
    let gear = k.command(1, Command::GearIn(GearIn::new(0, 1, 1))).unwrap();
    let before = steps(&mut k, 1500);
    let target = before.last().unwrap().1.set.p + 500.0;
    let ptp = k
        .command(
            1,
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, target).speed(100.0)),
        )
        .unwrap();
    assert_eq!(k.command_status(gear), CommandStatus::Aborted);
    let after = steps(&mut k, 7000);
    let f: Vec<_> = before.iter().chain(&after).map(|t| t.1).collect();
    assert_smooth(&f, None, 1000.0, 1e9, "MovePtp after GearIn");
    assert_eq!(k.command_status(ptp), CommandStatus::Done);
}

#[test]
fn a_modulo_gear_over_a_million_master_turns_keeps_exact_counts() {
    // Master 360° modulo at 1000 turns/s, follower 360° modulo at 3/7: after 10⁶ master
    // turns the follower has turned exactly 3/7 of that, to the count (1 count = 0.001°).
    let mut m = virtual_master();
    m.mechanics.modulo = Modulo::new(360.0);
    m.max.vmax = 360_000.0;
    m.max.amax = 1e6;
    m.max.dmax = 1e6;
    m.max.jmax = 1e9;
    m.defaults.acceleration = 1e6;
    m.defaults.jerk = 1e9;
    let mut f = follower("f");
    f.mechanics.modulo = Modulo::new(360.0);
    f.max.vmax = 200_000.0;
    f.max.amax = 1e6;
    f.max.dmax = 1e6;
    f.max.jmax = 1e9;
    f.defaults.acceleration = 1e6;
    f.defaults.deceleration = 1e6;
    f.defaults.jerk = 1e9;
    let mut k = kernel(vec![m, f]);
    k.command(1, Command::GearIn(GearIn::new(0, 3, 7))).unwrap();
    k.command(0, velocity(360_000.0)).unwrap();
    let counts = |s: &AxisStatus| s.turns as i128 * 360_000 + (s.set.p * 1000.0).round() as i128;
    let (m0, f0) = (
        counts(k.axis_status(0).unwrap()),
        counts(k.axis_status(1).unwrap()),
    );
    let mut worst = 0i128;
    let mut cycles = 0u64;
    while k.axis_status(0).unwrap().turns < 1_000_000 {
        k.step(&[]);
        cycles += 1;
        let (ms, fs) = (k.axis_status(0).unwrap(), k.axis_status(1).unwrap());
        assert!(fs.bits.in_sync, "in gear from the start (both at rest)");
        // 7 · follower travel against 3 · master travel, in counts.
        let err = 7 * (counts(fs) - f0) - 3 * (counts(ms) - m0);
        worst = worst.max(err.abs());
    }
    let ms = k.axis_status(0).unwrap();
    assert!(ms.turns >= 1_000_000 && cycles > 1_000_000);
    // Rounding each position to a count can differ by half a count on each side: 7 · ½ + 3 · ½.
    assert!(
        worst <= 5,
        "7·Δf − 3·Δm = {worst} counts after {cycles} cycles"
    );
}

#[test]
fn gear_in_pos_is_at_the_slave_sync_position_when_the_master_is_at_its_own() {
    let mut m = virtual_master();
    m.mechanics.modulo = Modulo::new(360.0);
    let mut f = follower("f");
    f.mechanics.modulo = Modulo::new(100.0);
    let mut k = kernel(vec![m, f]);
    k.command(0, velocity(180.0)).unwrap();
    steps(&mut k, 1000);
    let g = GearInPos {
        gear: GearIn::new(0, 1, 2),
        master_sync_position: 90.0,
        slave_sync_position: 30.0,
        master_start_distance: Some(200.0),
    };
    let h = k.command(1, Command::GearInPos(g)).unwrap();
    let trace = steps(&mut k, 6000);
    let f: Vec<_> = trace.iter().map(|t| t.1).collect();
    assert_smooth(&f, Some(100.0), 1000.0, 1e9, "GearInPos");
    // The follower stands until the master is 200° before 90° (at 250°), then catches up.
    let start = trace
        .iter()
        .position(|(_, s)| s.set.v.abs() > 1e-9)
        .expect("the follower starts");
    let m_at_start = trace[start].0.set.p;
    assert!(
        (m_at_start - 250.0).abs() <= 180.0 * DT * 1.01,
        "started at master {m_at_start}"
    );
    let sync = f.iter().position(|s| s.bits.in_sync).expect("in sync");
    // In sync exactly at the master's sync position: follower − 30 = ½ (master − 90).
    let (ms, fs) = (&trace[sync].0, &trace[sync].1);
    let dm = (ms.set.p - 90.0 + 180.0).rem_euclid(360.0) - 180.0;
    let df = (fs.set.p - 30.0 + 50.0).rem_euclid(100.0) - 50.0;
    assert!(
        (0.0..=180.0 * DT * 1.01).contains(&dm),
        "master {} past 90",
        ms.set.p
    );
    assert!(
        (df - 0.5 * dm).abs() < 1e-9,
        "follower {} master {}",
        fs.set.p,
        ms.set.p
    );
    // And on the gear line from there on (the master's travel counted over its turns).
    let turns0 = trace[sync].0.turns;
    for (ms, fs) in &trace[sync..] {
        let dm = (ms.turns - turns0) as f64 * 360.0 + ms.set.p - 90.0;
        let expect = (30.0 + 0.5 * dm).rem_euclid(100.0);
        let d = (fs.set.p - expect + 50.0).rem_euclid(100.0) - 50.0;
        assert!(d.abs() < 1e-9, "off the gear line by {d}");
    }
    assert_eq!(k.command_status(h), CommandStatus::Active);
}

#[test]
fn gear_in_pos_refusals_say_why() {
    let mut k = kernel(vec![virtual_master(), follower("f")]);
    k.command(0, velocity(100.0)).unwrap();
    steps(&mut k, 1000);
    let behind = GearInPos {
        gear: GearIn::new(0, 1, 1),
        master_sync_position: 0.0,
        slave_sync_position: 0.0,
        master_start_distance: None,
    };
    let e = k.command(1, Command::GearInPos(behind)).unwrap_err();
    assert!(e.to_string().contains("behind the master"), "{e}");
    k.command(1, velocity(10.0)).unwrap();
    steps(&mut k, 10);
    let moving = GearInPos {
        master_sync_position: 1e6,
        master_start_distance: Some(10.0),
        ..behind
    };
    let e = k.command(1, Command::GearInPos(moving)).unwrap_err();
    assert!(e.to_string().contains("must stand"), "{e}");
}

#[test]
fn gear_refusals_name_the_problem() {
    let mut k = kernel(vec![virtual_master(), follower("f"), follower("g")]);
    let e = k
        .command(1, Command::GearIn(GearIn::new(1, 1, 1)))
        .unwrap_err();
    assert!(e.to_string().contains("cannot follow itself"), "{e}");
    let e = k
        .command(1, Command::GearIn(GearIn::new(9, 1, 1)))
        .unwrap_err();
    assert!(e.to_string().contains("no such axis"), "{e}");
    let e = k
        .command(1, Command::GearIn(GearIn::new(0, 1, 0)))
        .unwrap_err();
    assert!(e.to_string().contains("ratio"), "{e}");
    let e = k
        .command(1, Command::GearIn(GearIn::new(0, 0, 1)))
        .unwrap_err();
    assert!(e.to_string().contains("numerator of 0"), "{e}");
    // g follows f follows m: m following g would be a loop.
    k.command(1, Command::GearIn(GearIn::new(0, 1, 1))).unwrap();
    k.command(2, Command::GearIn(GearIn::new(1, 1, 1))).unwrap();
    let e = k
        .command(0, Command::GearIn(GearIn::new(2, 1, 1)))
        .unwrap_err();
    assert!(e.to_string().contains("loop"), "{e}");
    // CamOut on a gearing axis, GearOut on a standing one.
    let e = k.command(1, Command::CamOut).unwrap_err();
    assert!(e.to_string().contains("not camming"), "{e}");
    let mut k = kernel(vec![virtual_master(), follower("f")]);
    assert!(matches!(
        k.command(1, Command::GearOut),
        Err(CommandError::NotAllowedInState { .. })
    ));
    // Catch-up dynamics above the follower's maxima.
    let mut g = GearIn::new(0, 1, 1);
    g.catch_up = CatchUp {
        acceleration: Some(1e9),
        ..CatchUp::default()
    };
    let e = k.command(1, Command::GearIn(g)).unwrap_err();
    assert!(e.to_string().contains("acceleration"), "{e}");
}

#[test]
fn a_chain_of_followers_is_stepped_master_first_in_the_same_cycle() {
    // Axis 0 follows axis 2, which follows axis 1 (the index order is the wrong one): each
    // still sees its master's values of the same cycle.
    let mut k = kernel(vec![follower("a"), virtual_master(), follower("b")]);
    k.command(2, Command::GearIn(GearIn::new(1, 2, 1))).unwrap();
    k.command(0, Command::GearIn(GearIn::new(2, 1, 4))).unwrap();
    k.command(1, velocity(50.0)).unwrap();
    for _ in 0..500 {
        k.step(&[]);
        let (a, m, b) = (
            k.axis_status(0).unwrap(),
            k.axis_status(1).unwrap(),
            k.axis_status(2).unwrap(),
        );
        assert!((b.set.p - 2.0 * m.set.p).abs() < 1e-9);
        assert!((a.set.p - 0.5 * m.set.p).abs() < 1e-9);
    }
}

#[test]
fn a_master_too_fast_for_the_follower_is_an_error_stop_or_a_warning_never_silent() {
    for reaction in [SyncLimitReaction::ErrorStop, SyncLimitReaction::Warning] {
        let mut f = follower("f");
        f.max.vmax = 120.0;
        f.sync_limit_reaction = reaction;
        let mut k = kernel(vec![virtual_master(), f]);
        let h = k.command(1, Command::GearIn(GearIn::new(0, 2, 1))).unwrap();
        k.command(0, velocity(100.0)).unwrap();
        let trace = steps(&mut k, 2000);
        let f: Vec<_> = trace.iter().map(|t| t.1).collect();
        match reaction {
            SyncLimitReaction::ErrorStop => {
                // Never above its maximum: it stopped following before.
                assert!(f.iter().all(|s| s.set.v.abs() <= 120.0 * (1.0 + 1e-9)));
                let last = f.last().unwrap();
                assert_eq!(last.state, AxisState::ErrorStop);
                let Some(AxisFault::SyncLimit(l)) = last.error else {
                    panic!("{:?}", last.error)
                };
                assert_eq!(l.quantity, "speed");
                assert_eq!(l.max, 120.0);
                assert!(last
                    .error
                    .unwrap()
                    .to_string()
                    .contains("above its maximum 120"));
                assert!(matches!(k.command_status(h), CommandStatus::Error(_)));
                assert_eq!(last.set.v, 0.0, "braked to a stop");
                assert_smooth(&f, None, 1000.0 * 1.001 + 2.0 * 1000.0, 1e9, "limit stop");
            }
            SyncLimitReaction::Warning => {
                let over: Vec<_> = f.iter().filter(|s| s.set.v > 120.0).collect();
                assert!(!over.is_empty());
                assert!(over.iter().all(|s| s.bits.sync_limit_exceeded));
                assert!(f
                    .iter()
                    .filter(|s| s.set.v <= 120.0)
                    .all(|s| !s.bits.sync_limit_exceeded));
                assert_eq!(f.last().unwrap().state, AxisState::SynchronizedMotion);
            }
        }
    }
}

/// An external encoder axis (fed by `feedback`) as master.
fn encoder() -> AxisConfig {
    let mut c = linear("enc");
    c.kind = AxisKind::External;
    c.max.vmax = 1000.0;
    c
}

#[test]
fn an_encoder_master_that_fails_puts_its_direct_followers_in_error_stop() {
    let mut k = Kernel::new(DT, vec![encoder(), follower("f")]).unwrap();
    k.command(
        1,
        Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
    )
    .unwrap();
    let mut fb = vec![AxisFeedback::default(); 2];
    k.step(&fb);
    let h = k.command(1, Command::GearIn(GearIn::new(0, 1, 1))).unwrap();
    let mut trace = Vec::new();
    for i in 0..3000u32 {
        fb[0].position = 0.05 * f64::from(i); // 50 units/s
        fb[0].velocity = 50.0;
        if i >= 1500 {
            fb[0].fault = Some(0x7300);
        }
        k.step(&fb);
        trace.push(*k.axis_status(1).unwrap());
    }
    let enc = k.axis_status(0).unwrap();
    assert_eq!(enc.state, AxisState::ErrorStop);
    let f = trace.last().unwrap();
    assert_eq!(f.state, AxisState::ErrorStop);
    assert_eq!(f.error, Some(AxisFault::MasterLost { master: 0 }));
    assert!(f
        .error
        .unwrap()
        .to_string()
        .contains("master axis 0 became unavailable"));
    assert!(matches!(k.command_status(h), CommandStatus::Error(_)));
    assert_eq!(f.set.v, 0.0);
    // It braked from the gear's velocity without a jump.
    assert_smooth(&trace[1400..], None, 1000.0 * 1.001, 1e9, "master lost");
    // A new gear on the failed master is refused until the encoder is back and reset.
    let e = k.command(1, Command::Reset).unwrap();
    assert_eq!(k.command_status(e), CommandStatus::Done);
    let e = k
        .command(1, Command::GearIn(GearIn::new(0, 1, 1)))
        .unwrap_err();
    assert!(matches!(
        e,
        CommandError::MasterNotAvailable { master: 0, .. }
    ));
    fb[0].fault = None;
    k.step(&fb);
    let r = k.command(0, Command::Reset).unwrap();
    k.step(&fb);
    assert_eq!(k.command_status(r), CommandStatus::Done);
    assert_eq!(k.axis_status(0).unwrap().state, AxisState::Disabled);
    k.command(1, Command::GearIn(GearIn::new(0, 1, 1))).unwrap();
}

#[test]
fn through_an_intermediate_virtual_axis_the_followers_ramp_down_together_in_sync() {
    let mut v = virtual_master();
    v.name = "v".into();
    v.max.dmax = 200.0;
    let mut k = Kernel::new(DT, vec![encoder(), v, follower("f"), follower("g")]).unwrap();
    for i in 1..4 {
        k.command(
            i,
            Command::Power(gantry_kernel::axis::command::PowerCommand::Enable),
        )
        .unwrap();
    }
    let mut fb = vec![AxisFeedback::default(); 4];
    k.step(&fb);
    k.command(1, Command::GearIn(GearIn::new(0, 1, 1))).unwrap();
    let hf = k.command(2, Command::GearIn(GearIn::new(1, 2, 1))).unwrap();
    let hg = k
        .command(3, Command::GearIn(GearIn::new(1, -1, 3)))
        .unwrap();
    let mut trace = Vec::new();
    for i in 0..4000u32 {
        fb[0].position = 0.04 * f64::from(i.min(1500)) + 0.0;
        fb[0].velocity = if i < 1500 { 40.0 } else { 0.0 };
        if i >= 1500 {
            // The encoder fails (its counter frozen, the module flags it).
            fb[0].fault = Some(0x7300);
        }
        k.step(&fb);
        trace.push((
            *k.axis_status(1).unwrap(),
            *k.axis_status(2).unwrap(),
            *k.axis_status(3).unwrap(),
        ));
    }
    let (v, f, g) = trace.last().unwrap();
    assert_eq!(v.state, AxisState::ErrorStop);
    assert_eq!(v.error, Some(AxisFault::MasterLost { master: 0 }));
    assert_eq!(v.set.v, 0.0, "the virtual axis ramped down");
    // The followers stayed with the virtual axis, in sync, all the way down.
    assert_eq!(f.state, AxisState::SynchronizedMotion);
    assert_eq!(g.state, AxisState::SynchronizedMotion);
    assert_eq!(k.command_status(hf), CommandStatus::Active);
    assert_eq!(k.command_status(hg), CommandStatus::Active);
    let (v0, f0, g0) = trace[1400];
    for (v, f, g) in &trace[1400..] {
        assert!(((f.set.p - f0.set.p) - 2.0 * (v.set.p - v0.set.p)).abs() < 1e-9);
        assert!(((g.set.p - g0.set.p) + (v.set.p - v0.set.p) / 3.0).abs() < 1e-9);
        assert!(f.bits.in_sync && g.bits.in_sync);
    }
    let vs: Vec<_> = trace.iter().map(|t| t.0).collect();
    // The ramp down took 40/200 = 0.2 s, not one cycle.
    let moving_after = vs[1500..].iter().filter(|s| s.set.v.abs() > 1e-9).count();
    assert!(
        (150..=260).contains(&moving_after),
        "ramped over {moving_after} cycles"
    );
}
