//! Drive counts end to end (issue 10 §1), on modulo axes turning many periods both ways:
//! gantry's engine drives catalog servos in the in-process simulator through the lockstep
//! rig (`gantry_tests::drive_counts`), and the drives judge what reached them.
//!
//! A drive counts in 32 bits and wraps; a modulo axis wraps its position every period.
//! Neither wrap may reach the drive as a step: the target it gets is the low half of a
//! continuous 64-bit count, whatever the kernel's frame, the number of periods turned,
//! a SetPosition offset, or where the drive's counter stood at power-up.

use gantry::runtime::controller::CommandHandle;
use gantry_drives::scaling::ScalingConfig;
use gantry_kernel::axis::command::{Command, HaltMode, MoveDirection, MoveVelocity};
use gantry_tests::drive_counts::{axis, scaling, Machine};

/// Rotary modulo axes whose periods are not whole numbers of counts (gears 7:3, 3:7 and
/// 13:5, a period that is not the feed constant) and one that is (the example machine's
/// 10:1 table), starting anywhere in their counters, turn a dozen periods and more one
/// way and twice as many back at speed: no drive ever sees a step, and each ends exactly
/// where the kernel's travel says, to the count.
#[test]
fn modulo_axes_turn_many_periods_both_ways_without_a_step() {
    let specs = vec![
        // 2^17 · 10 = 1 310 720 counts per 360°, the example's c axis.
        axis(
            "c",
            Some(360.0),
            2000.0,
            scaling(1 << 17, 10, 1, 360.0),
            5_000_000,
        ),
        // 10 000 · 7/3 = 23 333⅓ counts per 360°.
        axis(
            "r",
            Some(360.0),
            2000.0,
            scaling(10_000, 7, 3, 360.0),
            -1_234_567,
        ),
        // 2^20 · 3/7, inverted: 449 389.7… counts per 360°, counting down.
        axis(
            "s",
            Some(360.0),
            2000.0,
            ScalingConfig {
                invert: true,
                ..scaling(1 << 20, 3, 7, 360.0)
            },
            0,
        ),
        // 4096 · 13/5 per 360° of load, period 100°: 2958.2… counts.
        axis(
            "t",
            Some(100.0),
            2000.0,
            scaling(4096, 13, 5, 360.0),
            2_000_000_000,
        ),
    ];
    let mut rig = Machine::new(specs);
    rig.enable_all();
    let start: Vec<f64> = (0..4).map(|i| rig.counts(i)).collect();
    let start_units: Vec<f64> = (0..4).map(|i| rig.unwrapped_set(i)).collect();
    let velocity = |d| Command::MoveVelocity(MoveVelocity::new(d, 1440.0));
    // 3 s forward (12 turns of 360°, 43 periods of 100°), 6 s back, stop.
    for i in 0..4 {
        rig.command(i, velocity(MoveDirection::Positive));
    }
    let mut n = 0;
    rig.run_until(3000, "forward", |_| {
        n += 1;
        n == 3000
    });
    for i in 0..4 {
        rig.command(i, velocity(MoveDirection::Negative));
    }
    let mut n = 0;
    rig.run_until(6000, "back", |_| {
        n += 1;
        n == 6000
    });
    let halts: Vec<CommandHandle> = (0..4)
        .map(|i| {
            rig.command(
                i,
                Command::Halt {
                    mode: HaltMode::Normal,
                    deceleration: None,
                },
            )
        })
        .collect();
    rig.run_until(2000, "halt", |r| halts.iter().all(|h| r.done(h)));
    rig.settle(200);
    for i in 0..4 {
        // The kernel's travel since enabled (turns · period + position, no SetPosition
        // here) against what the drive travelled.
        let travel_units = rig.unwrapped_set(i) - start_units[i];
        let expect = rig.travel_counts(i, travel_units);
        let got = rig.counts(i) - start[i];
        assert!(
            (got - expect).abs() <= 2.0,
            "axis {}: drive travelled {got} counts, the kernel {travel_units} units = {expect} counts",
            rig.drives[i].axis
        );
        // It really turned: forward ~4320° then back ~8640°.
        assert!(
            travel_units < -3.0 * 360.0,
            "axis {}: travel {travel_units}",
            rig.drives[i].axis
        );
    }
    rig.assert_invariants();
}
