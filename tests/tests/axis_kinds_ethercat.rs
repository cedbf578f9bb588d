//! Every axis type on one simulated EtherCAT chain, in lockstep (seed 000 §2): a real axis
//! `x` on a servo (slave 0), a simulated `s` and a virtual `v` (no drive), an external `e`
//! on the simulator's encoder module (slave 1, an EL5101-like terminal whose shaft the
//! test turns at a set speed) and `h`, the shadow of `x`. The external axis follows the
//! shaft exactly in counts through the 32-bit counter's wrap; each type takes the commands
//! it may and refuses the others by name; the encoder's loss by each of its three reasons
//! reaches the external axis' feedback with its code, keeps its last good position and
//! puts the axis in ErrorStop until a Reset after the loss is gone. With the encoder as
//! master (seed 001): its direct follower `d` goes to ErrorStop naming it, while `v`, a
//! virtual axis between the encoder and `s`, ramps down and `s` comes down with it in
//! sync. One test: the EtherCAT bus starts once per process.

use gantry::runtime::cycle::COMMUNICATION_FAULT;
use gantry::runtime::encoder_input::{ENCODER_DATA_INVALID, ENCODER_FROZEN};
use gantry_kernel::axis::command::{
    Command, CommandError, HaltMode, MoveDirection, MovePtp, MoveVelocity, PositioningMode,
    PowerCommand,
};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::axis::status::{AxisFault, AxisStatus};
use gantry_kernel::sync::command::GearIn;
use gantry_sim::plant::encoder::EncoderModule;
use gantry_sim::plant::DeviceModel;
use gantry_tests::rig::Rig;
use gantry_tests::{sim_config_text, DEFAULT_SYNC_ERROR_LIMIT};

const X: usize = 0;
const S: usize = 1;
const V: usize = 2;
const E: usize = 3;
const H: usize = 4;
const D: usize = 5;
/// Encoder counts per revolution of the shaft (and per 360 units of `e`).
const COUNTS_PER_REV: f64 = 4096.0;

fn config() -> gantry::config::Config {
    let slaves = format!(
        "[[slave]]\nkind = \"servo\"\n[slave.al]\nsync_error_limit = {DEFAULT_SYNC_ERROR_LIMIT}\n\
         [[slave]]\nkind = \"encoder\"\ncounts_per_rev = 4096\n"
    );
    let max = "max = { speed = 20.0, acceleration = 200.0, jerk = 4000.0 }\n";
    // The intermediate virtual axis ramps down (ErrorStop) with its maximum deceleration
    // and jerk: slow enough for s, which follows it at 2:1 with at most 200.
    let max_v =
        "max = { speed = 20.0, acceleration = 200.0, deceleration = 80.0, jerk = 1000.0 }\n";
    let axes = format!(
        "[[axis]]\nname = \"x\"\ndrive = 0\npdo = \"csp-minimal\"\nhoming_required = false\n\
         scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n{max}\
         [[axis]]\nname = \"s\"\ntype = \"simulated\"\nhoming_required = false\n{max}\
         [[axis]]\nname = \"v\"\ntype = \"virtual\"\n{max_v}\
         [[axis]]\nname = \"e\"\ntype = \"external\"\nunits = \"deg\"\n\
         scaling = {{ counts_per_motor_rev = 4096, units_per_load_rev = 360.0 }}\n\
         [axis.encoder_input]\nslave = 1\nfreeze_timeout_ms = 10\n\
         [[axis]]\nname = \"h\"\ntype = \"shadow\"\nsource = \"x\"\n\
         [[axis]]\nname = \"d\"\ntype = \"simulated\"\nhoming_required = false\n{max}"
    );
    sim_config_text(1000, &slaves, "", &axes)
}

/// `f` of the simulated encoder module.
fn encoder<R>(rig: &Rig, f: impl FnOnce(&mut EncoderModule) -> R) -> R {
    let mut chain = rig.chain.lock().expect("the chain");
    match chain.slave_mut(1).expect("slave 1").device_mut() {
        DeviceModel::Encoder(e) => f(e),
        other => panic!("slave 1 is {other:?}"),
    }
}

/// The external axis' extended count as the master has it.
fn master_count(rig: &Rig) -> i64 {
    rig.engine
        .cycle
        .encoder_input(E)
        .and_then(|e| e.count())
        .expect("the encoder was read")
}

/// The fault code in the external axis' feedback (what the kernel gets).
fn feedback_fault(rig: &Rig) -> Option<u16> {
    rig.engine.cycle.feedback(E).expect("axis e").fault
}

fn refused(status: CommandStatus, command: &str, kind: &str) {
    let CommandStatus::Error(e) = status else {
        panic!("{command} on a {kind} axis: {status:?}");
    };
    assert!(
        matches!(e, CommandError::NotCommandable { .. }),
        "{command}: {e:?}"
    );
    assert_eq!(
        e.to_string(),
        format!("{command}: the axis is of type {kind}, which takes no motion or power commands")
    );
}

fn status(rig: &Rig, axis: usize) -> AxisStatus {
    *rig.engine.cycle.kernel.axis_status(axis).expect("axis")
}

/// The external axis is in ErrorStop for the encoder's `code`; once the loss is gone
/// (`clear`), Reset brings it back (Disabled: an encoder is never enabled).
fn assert_lost_then_reset(rig: &mut Rig, code: u16, clear: impl FnOnce(&mut Rig)) {
    let e = status(rig, E);
    assert_eq!(e.state, AxisState::ErrorStop);
    assert_eq!(e.error, Some(AxisFault::Encoder { code }));
    clear(rig);
    rig.run(3);
    assert_eq!(rig.command(E, Command::Reset), CommandStatus::Done);
    assert_eq!(status(rig, E).state, AxisState::Disabled);
}

#[test]
fn every_axis_type_on_one_chain() {
    let config = config();
    let mut rig = Rig::new(&config);
    // The shaft stands, its counter 16 counts below the wrap.
    encoder(&rig, |e| {
        e.shaft_speed_rev_s = 0.0;
        e.preset_counter(0xFFFF_FFF0);
    });
    rig.run(10);
    let (count0, shaft0) = (master_count(&rig), encoder(&rig, |e| e.position_counts()));
    assert_eq!(
        count0, -16,
        "the first value is the counter as a signed count"
    );

    // The shaft turns at 7.3 rev/s (29 900.8 counts/s, ~30 a cycle) for 4 s: through the
    // counter's wrap at once and on. Every cycle the master's count is the module's
    // counter as of the last exchange (at most two steps behind the module now: the
    // frame read what the module published a step before, and it has stepped since).
    encoder(&rig, |e| e.shaft_speed_rev_s = 7.3);
    let step = (7.3 * COUNTS_PER_REV * 1e-3_f64).ceil() as i64;
    let mut last = count0;
    for _ in 0..4000 {
        rig.cycle();
        let count = master_count(&rig);
        let module = i64::from(encoder(&rig, |e| e.counter()) as i32);
        assert!(count >= last, "never backwards: {last} → {count}");
        assert!(
            (count.wrapping_sub(module) as i32).unsigned_abs() as i64 <= 2 * step,
            "the master's count {count} is the module's counter {module:#x} (±2 steps)"
        );
        last = count;
        let fb = rig.engine.cycle.feedback(E).expect("e");
        assert_eq!(fb.fault, None);
    }
    let st = *rig.engine.cycle.kernel.axis_status(E).expect("e");
    assert!(
        (st.actual_velocity - 7.3 * 360.0).abs() < 360.0 * step as f64 / COUNTS_PER_REV * 1e3,
        "velocity {} deg/s",
        st.actual_velocity
    );
    // Stopped: the master's count moved exactly as the shaft did, across the wrap.
    encoder(&rig, |e| e.shaft_speed_rev_s = 0.0);
    rig.run(5);
    let (count1, shaft1) = (master_count(&rig), encoder(&rig, |e| e.position_counts()));
    assert!(shaft1 - shaft0 > 100_000, "a long run: {}", shaft1 - shaft0);
    assert_eq!(count1 - count0, shaft1 - shaft0, "exact in counts");
    let st = *rig.engine.cycle.kernel.axis_status(E).expect("e");
    assert_eq!(st.actual_position, count1 as f64 * 360.0 / COUNTS_PER_REV);
    assert_eq!(
        st.state,
        AxisState::Disabled,
        "an external axis is never enabled"
    );

    // Commands each type takes.
    for axis in [X, S, V] {
        assert_eq!(
            rig.command(axis, Command::Power(PowerCommand::Enable)),
            CommandStatus::Done,
            "enable axis {axis}"
        );
        let set = Command::SetPosition {
            position: 0.0,
            relative: false,
        };
        assert_eq!(rig.command(axis, set), CommandStatus::Done);
        let ptp = Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 2.0));
        assert_eq!(rig.command(axis, ptp), CommandStatus::Done, "ptp {axis}");
        let st = *rig.engine.cycle.kernel.axis_status(axis).expect("axis");
        assert!((st.set.p - 2.0).abs() < 1e-9, "axis {axis}: {st:?}");
        let velocity = Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 5.0));
        let h = rig.ctl.command(axis, velocity).expect("queued");
        rig.run(300);
        assert_eq!(
            rig.status_now(&h),
            Some(CommandStatus::Active),
            "axis {axis}"
        );
        let halt = Command::Halt {
            mode: HaltMode::Normal,
            deceleration: None,
        };
        assert_eq!(rig.command(axis, halt), CommandStatus::Done, "halt {axis}");
        assert_eq!(
            rig.command(axis, Command::Stop { deceleration: None }),
            CommandStatus::Done,
            "stop {axis}"
        );
        assert_eq!(rig.command(axis, Command::Release), CommandStatus::Done);
        let h = rig.ctl.reset(axis).expect("queued");
        assert_eq!(rig.finish(&h, 100), CommandStatus::Done, "reset {axis}");
    }
    // Simulated and virtual axes: actual = set.
    for axis in [S, V] {
        let st = *rig.engine.cycle.kernel.axis_status(axis).expect("axis");
        assert_eq!(st.actual_position, st.set.p, "axis {axis}");
    }
    // The shadow mirrors x's actual position.
    rig.run(1);
    let (x, h) = (
        *rig.engine.cycle.kernel.axis_status(X).expect("x"),
        *rig.engine.cycle.kernel.axis_status(H).expect("h"),
    );
    assert!(
        (h.actual_position - x.actual_position).abs() < 1e-6,
        "{h:?} {x:?}"
    );
    // External and shadow axes are never commanded; SetPosition (bookkeeping) they take.
    for (axis, kind) in [(E, "external"), (H, "shadow")] {
        let commands = [
            Command::Power(PowerCommand::Enable),
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 1.0)),
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 1.0)),
            Command::Halt {
                mode: HaltMode::Normal,
                deceleration: None,
            },
            Command::Stop { deceleration: None },
            Command::GearIn(GearIn::new(X, 1, 1)),
        ];
        for c in commands {
            let name = c.name();
            refused(rig.command(axis, c), name, kind);
        }
        // Reset (nothing to acknowledge) is done at once.
        assert_eq!(rig.command(axis, Command::Reset), CommandStatus::Done);
        let h = rig.ctl.reset(axis).expect("queued");
        assert_eq!(rig.finish(&h, 100), CommandStatus::Done, "{kind}");
        let set = Command::SetPosition {
            position: 10.0,
            relative: true,
        };
        assert_eq!(rig.command(axis, set), CommandStatus::Done, "{kind}");
    }

    // The encoder as master: d follows it directly, v through a gear and s follows v.
    encoder(&rig, |e| e.shaft_speed_rev_s = 2.0); // 720 °/s
    rig.run(20);
    for axis in [V, S, D] {
        assert_eq!(
            rig.command(axis, Command::Power(PowerCommand::Enable)),
            CommandStatus::Done
        );
    }
    for (axis, master, num, den) in [(D, E, 1, 100), (V, E, 1, 100), (S, V, 2, 1)] {
        let h = rig
            .ctl
            .command(axis, Command::GearIn(GearIn::new(master, num, den)))
            .expect("queued");
        // Each caught up before the next (s at twice v's catching up would exceed its own
        // acceleration: an ErrorStop, rightly).
        rig.run(500);
        assert_eq!(
            rig.status_now(&h),
            Some(CommandStatus::Active),
            "axis {axis}"
        );
    }
    for axis in [V, S, D] {
        let st = status(&rig, axis);
        assert!(st.bits.gearing && st.bits.in_sync, "axis {axis}: {st:?}");
        assert_eq!(st.state, AxisState::SynchronizedMotion);
    }
    assert!(
        (status(&rig, S).set.v - 14.4).abs() < 0.5,
        "{:?}",
        status(&rig, S)
    );

    // Encoder loss, reason (b): the module's error bit (TxPDO State).
    let (v0, s0) = (status(&rig, V), status(&rig, S));
    encoder(&rig, |e| e.set_data_invalid(true));
    let mut down = Vec::new();
    let mut held = None;
    for _ in 0..300 {
        rig.cycle();
        let fb = rig.engine.cycle.feedback(E).expect("e");
        if fb.fault.is_some() {
            held.get_or_insert(fb.position);
        }
        down.push((status(&rig, V), status(&rig, S)));
    }
    let held = held.expect("the loss was seen");
    assert_eq!(feedback_fault(&rig), Some(ENCODER_DATA_INVALID));
    assert_eq!(
        rig.engine.cycle.feedback(E).expect("e").position,
        held,
        "no jump"
    );
    // The direct follower: ErrorStop, naming its master.
    let d = status(&rig, D);
    assert_eq!(d.state, AxisState::ErrorStop);
    assert_eq!(d.error, Some(AxisFault::MasterLost { master: E }));
    assert_eq!(d.set.v, 0.0);
    // The virtual axis ramped down (its maximum deceleration 80 and jerk 1000: 7.2 → 0
    // in about 0.17 s, not at once) and s came down with it, in gear all the way.
    let (v1, s1) = down.last().expect("cycles");
    assert_eq!(v1.state, AxisState::ErrorStop);
    assert_eq!(v1.error, Some(AxisFault::MasterLost { master: E }));
    assert_eq!(v1.set.v, 0.0);
    let ramp = down.iter().filter(|(v, _)| v.set.v.abs() > 1e-9).count();
    assert!((120..=220).contains(&ramp), "ramped over {ramp} cycles");
    assert_eq!(s1.state, AxisState::SynchronizedMotion, "{s1:?}");
    assert_eq!(s1.set.v, 0.0);
    for (v, s) in &down {
        let dv = v.set.p - v0.set.p;
        assert!(((s.set.p - s0.set.p) - 2.0 * dv).abs() < 1e-9, "s left v");
    }
    assert_lost_then_reset(&mut rig, ENCODER_DATA_INVALID, |rig| {
        encoder(rig, |e| e.set_data_invalid(false))
    });
    assert_eq!(feedback_fault(&rig), None, "back once the bit clears");
    for axis in [V, D] {
        assert_eq!(rig.command(axis, Command::Reset), CommandStatus::Done);
        assert_eq!(status(&rig, axis).state, AxisState::Standstill);
    }
    // The shaft turns on at 2 rev/s (8.2 counts a cycle): within two steps of it.
    let behind = (encoder(&rig, |e| e.position_counts()) - shaft1) - (master_count(&rig) - count1);
    assert!(
        (0..=18).contains(&behind),
        "the count went on with the shaft: {behind} counts behind"
    );

    // Reason (c): frozen — the toggle stands still; lost after 10 ms, not before.
    encoder(&rig, |e| e.set_frozen(true));
    rig.run(10);
    assert_eq!(feedback_fault(&rig), None, "within the freeze timeout");
    rig.run(3);
    assert_eq!(feedback_fault(&rig), Some(ENCODER_FROZEN));
    let held = rig.engine.cycle.feedback(E).expect("e").position;
    rig.run(20);
    assert_eq!(feedback_fault(&rig), Some(ENCODER_FROZEN));
    assert_eq!(
        rig.engine.cycle.feedback(E).expect("e").position,
        held,
        "no jump"
    );
    assert_lost_then_reset(&mut rig, ENCODER_FROZEN, |rig| {
        encoder(rig, |e| e.set_frozen(false))
    });
    assert_eq!(feedback_fault(&rig), None);

    // Reason (a): unreachable — the module stops exchanging process data; the bus faults
    // it (its working counter) and the axis gets the communication fault.
    rig.chain
        .lock()
        .expect("the chain")
        .stop_process_data(Some(1));
    rig.run(50);
    assert_eq!(feedback_fault(&rig), Some(COMMUNICATION_FAULT));
    assert!(rig.bus_fault(E).is_some(), "the bus names the module lost");
    let held = rig.engine.cycle.feedback(E).expect("e").position;
    rig.run(20);
    assert_eq!(
        rig.engine.cycle.feedback(E).expect("e").position,
        held,
        "no jump"
    );
    // (A process-data working counter cannot tell which slave failed to take part: the
    // bus faults the servo's axis too, as it does for any such loss.)
    rig.chain.lock().expect("the chain").stop_process_data(None);
    // A reset of the external axis brings its module back on the bus and acknowledges
    // the loss: the axis leaves ErrorStop.
    assert_eq!(
        status(&rig, E).error,
        Some(AxisFault::Encoder {
            code: COMMUNICATION_FAULT
        })
    );
    let h = rig.ctl.reset(E).expect("queued");
    assert_eq!(rig.finish(&h, 2000), CommandStatus::Done);
    rig.run(5);
    assert_eq!(rig.bus_fault(E), None);
    assert_eq!(feedback_fault(&rig), None, "the module is back");
    assert_eq!(status(&rig, E).state, AxisState::Disabled);
    encoder(&rig, |e| e.shaft_speed_rev_s = 0.0);
    rig.run(5);
    assert_eq!(
        master_count(&rig) - count1,
        encoder(&rig, |e| e.position_counts()) - shaft1,
        "exact after every loss"
    );
}
