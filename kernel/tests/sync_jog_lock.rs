//! Logix MAJ driven by a master (MDAC): lock position and lock direction, in lockstep.

mod common;

use common::sync::*;
use common::*;
use gantry_kernel::axis::command::{Command, MoveDirection};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::sync::command::{CatchUp, LockDirection, MasterJog, MasterValue};

fn jog(lock: LockDirection, lock_position: f64) -> MasterJog {
    MasterJog {
        master: 0,
        source: MasterValue::Set,
        direction: MoveDirection::Positive,
        speed: 0.5,
        lock,
        lock_position,
        catch_up: CatchUp::default(),
    }
}

#[test]
fn position_forward_only_locks_at_the_lock_position_and_follows_only_forward() {
    let mut k = kernel(vec![virtual_master(), follower("f")]);
    let h = k
        .command(
            1,
            Command::MasterJog(jog(LockDirection::PositionForwardOnly, 100.0)),
        )
        .unwrap();
    assert_eq!(k.command_status(h), CommandStatus::Active);
    k.command(0, velocity(50.0)).unwrap();
    let mut trace = steps(&mut k, 4000); // to master ≈ 195
                                         // Before the lock position the follower stands, and the lock is not set.
    for (m, f) in &trace {
        if m.set.p < 100.0 {
            assert_eq!(f.set.v, 0.0);
            assert!(!f.bits.jog_locked && f.bits.jogging);
        }
    }
    let lock = trace
        .iter()
        .position(|(_, f)| f.bits.jog_locked)
        .expect("locked");
    assert!((trace[lock].0.set.p - 100.0).abs() <= 50.0 * DT * 1.01);
    // After catching up: 0.5 · the master's speed.
    let last = trace.last().unwrap();
    assert!((last.1.set.v - 25.0).abs() < 1e-9, "{}", last.1.set.v);
    // The master reverses: the follower stops following and stands while it goes back.
    k.command(0, velocity(-50.0)).unwrap();
    trace.extend(steps(&mut k, 3000));
    let (m, f) = trace.last().unwrap();
    assert!(m.set.v < 0.0);
    assert_eq!(f.set.v, 0.0);
    assert!(!f.bits.jog_locked);
    // Forward again: the lock is set again and it follows again.
    k.command(0, velocity(50.0)).unwrap();
    trace.extend(steps(&mut k, 3000));
    let (_, f) = trace.last().unwrap();
    assert!(f.bits.jog_locked);
    assert!((f.set.v - 25.0).abs() < 1e-9);
    assert_eq!(f.state, AxisState::SynchronizedMotion);
    let fs: Vec<_> = trace.iter().map(|t| t.1).collect();
    assert_smooth(&fs, None, 1000.0, f64::INFINITY, "MAJ lock");
    // The acceleration is continuous but where the lock lets go: the master stands at that
    // moment (velocities continuous, both 0), and the follower's acceleration, ½ the
    // master's braking, stops at once (as Logix' lock does), no more than that.
    for (i, w) in fs.windows(2).enumerate() {
        let da = (w[1].set.a - w[0].set.a).abs();
        if da > 30_000.0 * DT * 1.001 {
            assert!(
                w[0].bits.jog_locked && !w[1].bits.jog_locked,
                "cycle {i}: {da}"
            );
            assert!(da <= 0.5 * 200.0 * 1.001, "cycle {i}: {da}");
            assert!(w[0].set.v.abs() < 0.5 * 200.0 * DT, "cycle {i}: {:?}", w[0]);
        }
    }
    // It moved only forward, never back.
    assert!(fs.iter().all(|s| s.set.v >= -1e-12));
    // Halt ends the jog like any jog.
    k.command(
        1,
        Command::Halt {
            mode: gantry_kernel::axis::command::HaltMode::Normal,
            deceleration: None,
        },
    )
    .unwrap();
    assert_eq!(k.command_status(h), CommandStatus::Aborted);
}

#[test]
fn immediate_reverse_only_follows_the_master_backwards_at_once() {
    let mut k = kernel(vec![virtual_master(), follower("f")]);
    k.command(0, velocity(-40.0)).unwrap();
    steps(&mut k, 500);
    let mut j = jog(LockDirection::ImmediateReverseOnly, 0.0);
    j.direction = MoveDirection::Negative;
    k.command(1, Command::MasterJog(j)).unwrap();
    let trace = steps(&mut k, 1000);
    let (_, f) = trace.last().unwrap();
    assert!(f.bits.jog_locked);
    // The jog's direction (negative) at half the master's speed.
    assert!((f.set.v + 20.0).abs() < 1e-9, "{}", f.set.v);
    let fs: Vec<_> = trace.iter().map(|t| t.1).collect();
    assert_smooth(&fs, None, 1000.0, 30_000.0, "MAJ immediate");
}

#[test]
fn master_driven_jog_refusals_say_why() {
    let mut k = kernel(vec![virtual_master(), follower("f")]);
    let mut j = jog(LockDirection::None, 0.0);
    j.speed = 0.0;
    let e = k.command(1, Command::MasterJog(j)).unwrap_err();
    assert!(
        e.to_string().contains("Jog.MasterDriven: operand speed"),
        "{e}"
    );
    let mut j = jog(LockDirection::None, 0.0);
    j.master = 1;
    let e = k.command(1, Command::MasterJog(j)).unwrap_err();
    assert!(e.to_string().contains("cannot follow itself"), "{e}");
}
