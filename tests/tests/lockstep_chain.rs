//! A whole machine on the simulated bus, lockstep in one thread: 8 catalog servos, an
//! encoder module and a digital-input module whose switch cams sit on servo 0's travel,
//! all in the simulator's configuration. gantry's engine (`gantry_tests::rig`) brings all
//! 10 slaves to OP, enables the 8 drives and runs a PTP move on each (Controller commands);
//! every cycle the test also reads the encoder (whose shaft it turns, and whose counter the
//! master sets once: the test writes the module's outputs in the bus' process image) and
//! the switch inputs.
//!
//! Each cycle's frame brings back the slaves' inputs as that cycle's tick left them. The
//! switch module gets servo 0's position actual value after that same tick, so servo 0's
//! position and the switch bits in one frame must agree exactly.

use gantry::config::Config;
use gantry::runtime::bus::CycleBus;
use gantry_drives::cia402::State;
use gantry_drives::csp::CspInputs;
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_sim::plant::encoder::{control, status};
use gantry_sim::plant::switches::SwitchCam;
use gantry_sim::plant::DeviceModel;
use gantry_tests::ball_screw_5mm;
use gantry_tests::invariant::{assert_drive_invariants, DriveUnderTest, TestConditions};
use gantry_tests::rig::Rig;

const DT: f64 = 1e-3;
const DRIVES: usize = 8;
const ENCODER: usize = 8;
const SWITCHES: usize = 9;
const COUNTS_PER_REV: u32 = 4096;

/// Servo 0 starts inside the negative limit switch and runs slowly past the reference
/// switch into the positive limit switch (counts; 2^17 counts = 5 mm).
const SERVO0_START: i32 = -52_429; // ≈ −2 mm
const SERVO0_TARGET_MM: f64 = 9.0;
const SERVO0_SPEED_MM_S: f64 = 2.0; // ≈ 52 counts per cycle

/// Servo 0's cams (counts). Around servo 0's target `t` three cams check the edges to
/// the count where the servo comes to rest: one starting at `t`, one ending one count
/// before, one ending at `t`.
fn cams(t: i64) -> Vec<SwitchCam> {
    let no = |input, from, to| SwitchCam {
        input,
        from,
        to,
        normally_closed: false,
    };
    vec![
        // Negative limit switch (normally closed).
        SwitchCam {
            input: 0,
            from: i64::MIN,
            to: -40_000,
            normally_closed: true,
        },
        // Reference switch.
        no(1, 50_000, 80_000),
        // Positive limit switch (normally closed): servo 0's target lies beyond it.
        SwitchCam {
            input: 2,
            from: 200_000,
            to: i64::MAX,
            normally_closed: true,
        },
        // A cam outside the travel.
        no(3, 1_000_000, 1_000_100),
        no(4, t, t + 1000),
        no(5, t - 1000, t - 1),
        no(6, t - 1000, t),
    ]
}

/// The master sets the encoder's counter to this value, close to the wrap.
const SET_VALUE: u32 = u32::MAX - 20_000;
const SET_AT_CYCLE: u32 = 3000;

/// Where the test puts the encoder's shaft before tick `k` (counts): backwards below 0
/// (the counter underflows), then forwards past 0 (it overflows) and on.
fn shaft_at(k: u32) -> i64 {
    let k = i64::from(k);
    if k <= 1000 {
        -37 * k
    } else {
        -37_000 + 61 * (k - 1000)
    }
}

fn target_mm(drive: usize) -> f64 {
    if drive == 0 {
        SERVO0_TARGET_MM
    } else {
        10.0 + 7.0 * drive as f64
    }
}

/// Servo 0's target in counts.
fn servo0_target_counts() -> i64 {
    ball_screw_5mm().units_to_counts(SERVO0_TARGET_MM)
}

/// The machine: servos at their power-up counts, the encoder and the switch module (the
/// simulator's TOML), without distributed clocks as the chain always ran here (the drives
/// SM-synchronous); axes `a0`…`a7` with the kernel's default limits (100 mm/s,
/// 1000 mm/s², 10 000 mm/s³), no homing, on the drives' minimal CSP mapping (6 bytes each
/// way, as the drives' EEPROM defaults give it).
fn config() -> Config {
    let mut slaves: String = (0..DRIVES)
        .map(|i| {
            let start = if i == 0 {
                SERVO0_START
            } else {
                1000 * i as i32
            };
            format!("[[slave]]\nkind = \"servo\"\nstart_position = {start}\n")
        })
        .collect();
    slaves += &format!(
        "[[slave]]\nkind = \"encoder\"\ncounts_per_rev = {COUNTS_PER_REV}\nshaft_speed = 0.0\n\
         [[slave]]\nkind = \"switches\"\naxis = 0\n"
    );
    for cam in cams(servo0_target_counts()) {
        slaves += &format!(
            "[[slave.cam]]\ninput = {}\nfrom = {}\nto = {}\nnormally_closed = {}\n",
            cam.input, cam.from, cam.to, cam.normally_closed
        );
    }
    let axes: String = (0..DRIVES)
        .map(|i| {
            format!(
                "[[axis]]\nname = \"a{i}\"\ndrive = {i}\nhoming_required = false\n\
                 pdo = \"csp-minimal\"\n\
                 scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
                 max = {{ speed = 100.0, acceleration = 1000.0, jerk = 10000.0 }}\n"
            )
        })
        .collect();
    gantry_tests::sim_config_text((DT * 1e6) as u32, &slaves, "dc = false", &axes)
}

fn turn_shaft(rig: &Rig, counts: i64) {
    match rig
        .chain
        .lock()
        .unwrap()
        .slave_mut(ENCODER)
        .unwrap()
        .device_mut()
    {
        DeviceModel::Encoder(e) => e.set_shaft_position(counts as f64 / f64::from(COUNTS_PER_REV)),
        other => panic!("slave {ENCODER} is {other:?}"),
    }
}

/// Servo 0's inputs in the frame the last cycle exchanged, as gantry's drive layer decodes
/// them (the kernel takes them at the start of the next cycle).
fn servo0_in_frame(rig: &Rig) -> CspInputs {
    rig.engine
        .cycle
        .channel(0)
        .and_then(|c| c.decode(rig.engine.bus.inputs(0)))
        .expect("servo 0's inputs")
}

/// The input level a cam gives at `position`, written out here rather than taken from the
/// model: actuated from `from` to `to`, both included; a normally closed contact inverts.
fn expected_level(cam: &SwitchCam, position: i64) -> bool {
    let actuated = cam.from <= position && position <= cam.to;
    actuated != cam.normally_closed
}

/// What the test saw of the switch inputs: per input, where its bit changed (servo 0's
/// actual position in the frame before and in the frame with the new level).
#[derive(Default)]
struct SwitchLog {
    flips: [Vec<(i64, i64, bool)>; 8],
}

#[test]
fn eight_drives_encoder_and_switches_to_op_and_ptp_on_every_drive() {
    let config = config();
    let mut rig = Rig::new(&config);
    assert_eq!(rig.engine.bus.drives(), 10);
    for i in 0..10 {
        let sizes = (
            rig.engine.bus.inputs(i).len(),
            rig.engine.bus.outputs(i).len(),
        );
        let expected = match i {
            ENCODER => (10, 6),
            SWITCHES => (1, 0),
            _ => (6, 6),
        };
        assert_eq!(sizes, expected, "subdevice {i}");
    }

    for i in 0..DRIVES {
        rig.ctl
            .command(i, Command::Power(PowerCommand::Enable))
            .expect("queued");
    }
    let scaling = ball_screw_5mm();
    let cams = cams(servo0_target_counts());

    // The shaft where the world's first step leaves it, so every input the master reads
    // comes from a tick.
    let mut shaft = shaft_at(0);
    turn_shaft(&rig, shaft);

    let mut moves: Vec<_> = Vec::new();
    let mut done_at = None;
    let mut in_op_at = None;
    let mut enc_control = 0u16;
    let mut shaft_at_set: Option<i64> = None;
    let mut underflow_seen = false;
    let mut overflow_rises = 0;
    let mut last_status = 0u16;
    let mut log = SwitchLog::default();
    let mut last: Option<(i64, u8)> = None;
    let (mut servo0_first, mut servo0_last) = (None, 0i64);
    for k in 1..12_000u32 {
        // The world moves one cycle; the kernel steps on the last frame's drive inputs,
        // its outputs go out in this cycle's frame, which brings back the inputs this
        // cycle's tick left.
        rig.cycle();
        if in_op_at.is_none()
            && (0..10).all(|i| rig.chain.lock().unwrap().slaves()[i].al_status() == 0x08)
        {
            in_op_at = Some(k);
        }

        // Encoder: the counter is the shaft's count until the master sets it, then the set
        // value plus the shaft's motion since.
        let (st, counter) = {
            let i = rig.engine.bus.inputs(ENCODER);
            (
                u16::from_le_bytes([i[0], i[1]]),
                u32::from_le_bytes([i[2], i[3], i[4], i[5]]),
            )
        };
        if st & status::SET_COUNTER_DONE != 0 && shaft_at_set.is_none() {
            assert_eq!(counter, SET_VALUE, "cycle {k}: loaded with the set value");
            shaft_at_set = Some(shaft);
        }
        let expected = match shaft_at_set {
            None => shaft as u32,
            Some(s0) => SET_VALUE.wrapping_add((shaft - s0) as u32),
        };
        assert_eq!(counter, expected, "cycle {k}: shaft at {shaft}");
        underflow_seen |= st & status::COUNTER_UNDERFLOW != 0;
        if st & !last_status & status::COUNTER_OVERFLOW != 0 {
            overflow_rises += 1;
        }
        last_status = st;
        // The set-counter handshake: raise, wait for the acknowledgement, lower (in the
        // process image: the next cycle's frame takes it).
        if k == SET_AT_CYCLE {
            enc_control = control::SET_COUNTER;
        } else if st & status::SET_COUNTER_DONE != 0 {
            enc_control = 0;
        }
        {
            let o = rig.engine.bus.outputs_mut(ENCODER);
            o[0..2].copy_from_slice(&enc_control.to_le_bytes());
            o[2..6].copy_from_slice(&SET_VALUE.to_le_bytes());
        }

        // Switches: every bit is its cam's level at servo 0's position in the same frame.
        let servo0_inputs = servo0_in_frame(&rig);
        let servo0 = i64::from(servo0_inputs.position);
        let byte = rig.engine.bus.inputs(SWITCHES)[0];
        if servo0_inputs.statusword.state().is_some() {
            for cam in &cams {
                let bit = byte >> cam.input & 1 != 0;
                assert_eq!(
                    bit,
                    expected_level(cam, servo0),
                    "cycle {k}: input {} at {servo0}",
                    cam.input
                );
            }
            if let Some((prev, prev_byte)) = last {
                for cam in &cams {
                    let (was, is) = (prev_byte >> cam.input & 1, byte >> cam.input & 1);
                    if was != is {
                        log.flips[usize::from(cam.input)].push((prev, servo0, is != 0));
                    }
                }
            }
            last = Some((servo0, byte));
            servo0_first.get_or_insert(servo0);
            servo0_last = servo0;
        }

        // The script: once every axis stands enabled, one PTP move each.
        let standstill = (0..DRIVES).all(|i| rig.state(i) == AxisState::Standstill);
        if moves.is_empty() && standstill {
            for i in 0..DRIVES {
                let mut m = MovePtp::new(PositioningMode::AbsNormal, target_mm(i));
                if i == 0 {
                    m = m.speed(SERVO0_SPEED_MM_S);
                }
                moves.push(rig.ctl.command(i, Command::MovePtp(m)).expect("queued"));
            }
        }
        let all_done = !moves.is_empty()
            && moves
                .iter()
                .all(|h| rig.status_now(h).is_some_and(|s| s.is_final()));
        if all_done && done_at.is_none() {
            done_at = Some(k);
        }
        // 100 ms after the last move ended to let the drives settle, and past the overflow.
        if done_at.is_some_and(|d| k >= d + 100) && overflow_rises >= 2 {
            break;
        }

        // Where the shaft stands for the next cycle's tick.
        shaft = shaft_at(k);
        turn_shaft(&rig, shaft);
    }
    // The engine took all 10 slaves to OP together (ethercrab's bring-up used to, before
    // the cycle started).
    let in_op_at = in_op_at.expect("all 10 slaves in OP");
    eprintln!("all 10 slaves in OP in cycle {in_op_at}");

    // Every drive on its target: set value exact, actual within a count.
    let done_at = done_at.expect("all moves ended");
    for (i, h) in moves.iter().enumerate() {
        assert_eq!(rig.status_now(h), Some(CommandStatus::Done), "drive {i}");
        let s = rig.engine.cycle.kernel.axis_status(i).unwrap();
        let target = target_mm(i);
        assert!(
            (s.set.p - target).abs() < 1e-9,
            "drive {i}: set {}",
            s.set.p
        );
        assert!(
            (s.actual_position - target).abs() < 1e-3,
            "drive {i}: actual {} mm, target {target} mm",
            s.actual_position
        );
        let (state, actual_counts) = rig.servo(i, |d| (d.state(), d.actual_counts()));
        assert_eq!(state, State::OperationEnabled);
        let target_counts = scaling.units_to_counts(target);
        assert!(
            (i64::from(actual_counts) - target_counts).abs() <= 1,
            "drive {i}: {actual_counts} counts, target {target_counts}"
        );
    }
    assert!(
        done_at > 5000,
        "servo 0's slow move takes ≈ 5.5 s: {done_at}"
    );

    // The encoder followed the shaft through an underflow, a set counter and two overflows.
    assert!(
        shaft_at_set.is_some(),
        "the set-counter handshake completed"
    );
    assert!(underflow_seen);
    assert_eq!(overflow_rises, 2);

    // The switches changed exactly where servo 0's actual position crossed a cam edge:
    // between the last frame before the edge and the first at or past it.
    let (start, end) = (servo0_first.unwrap(), servo0_last);
    assert_eq!(start, i64::from(SERVO0_START));
    assert_eq!(end, scaling.units_to_counts(SERVO0_TARGET_MM));
    for cam in &cams {
        // The first position inside the cam and the first one past it, moving forwards.
        let edges: Vec<i64> = [Some(cam.from), cam.to.checked_add(1)]
            .into_iter()
            .flatten()
            .filter(|&e| start < e && e <= end)
            .collect();
        let flips = &log.flips[usize::from(cam.input)];
        assert_eq!(
            flips.len(),
            edges.len(),
            "input {}: flips {flips:?}, edges {edges:?}",
            cam.input
        );
        for (&(before, at, level), &edge) in flips.iter().zip(&edges) {
            assert!(
                before < edge && edge <= at,
                "input {}: changed between {before} and {at}, edge at {edge}",
                cam.input
            );
            assert_eq!(level, expected_level(cam, edge));
        }
    }
    assert_eq!(log.flips[0].len(), 1, "negative limit left");
    assert_eq!(log.flips[1].len(), 2, "reference switch passed");
    assert_eq!(log.flips[2].len(), 1, "positive limit reached");
    assert!(
        log.flips[3].is_empty(),
        "the cam outside the travel never fires"
    );
    // At rest on the target: off the negative limit (NC: high), on the positive limit
    // (NC: low), on the cams that start or end at the target, off the one that ends a
    // count before.
    let byte_at_rest = last.unwrap().1;
    assert_eq!(byte_at_rest, 0b0101_0001, "{byte_at_rest:#010b}");
    eprintln!(
        "moves done after {done_at} cycles; switch flips (before, at, level): {:?}",
        log.flips
    );
    let drives = DriveUnderTest::of_config(&config);
    // Lockstep: one exchange per drive cycle, so no setpoint may be missed or doubled.
    let locked = TestConditions {
        phase_locked: true,
        ..TestConditions::default()
    };
    assert_drive_invariants(&rig.chain.lock().unwrap(), &drives, DT, locked);
    // Every slave is still in OP at the end — the input-only encoder and switch modules
    // too: with no outputs there is nothing for their process-data watchdog to watch.
    let states: Vec<u16> = (0..10)
        .map(|i| rig.chain.lock().unwrap().slaves()[i].al_status())
        .collect();
    assert_eq!(states, [0x08; 10], "AL status of each slave at the end");
}
