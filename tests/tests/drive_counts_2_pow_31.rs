//! Drive counts end to end (issue 10 §1): drive counters crossing ±2³¹, through gantry's
//! engine on the lockstep rig (`gantry_tests::drive_counts`); the drives judge what
//! reached them.

use gantry::runtime::controller::CommandHandle;
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode};
use gantry_tests::drive_counts::{axis, counter_difference, scaling, Machine};

/// Drive counters crossing ±2³¹, on a linear axis each way and on a modulo axis each way:
/// the drive wraps its 32-bit count (its target is the low half of gantry's 64-bit count)
/// and the axis goes on smoothly past it and back — the old code froze a linear axis'
/// target at the drive's actual without a word.
#[test]
fn drive_counters_cross_plus_and_minus_2_pow_31_counts() {
    let specs = vec![
        axis(
            "x",
            None,
            250.0,
            scaling(1 << 17, 1, 1, 5.0),
            i32::MAX - 100_000,
        ),
        axis(
            "y",
            None,
            250.0,
            scaling(1 << 17, 1, 1, 5.0),
            i32::MIN + 100_000,
        ),
        axis(
            "c",
            Some(360.0),
            720.0,
            scaling(1 << 17, 10, 1, 360.0),
            i32::MAX - 100_000,
        ),
        axis(
            "d",
            Some(360.0),
            720.0,
            scaling(10_000, 7, 3, 360.0),
            i32::MIN + 1_000,
        ),
    ];
    let mut rig = Machine::new(specs);
    rig.enable_all();
    let start: Vec<f64> = (0..4).map(|i| rig.counts(i)).collect();
    let p0: Vec<f64> = (0..4).map(|i| rig.unwrapped_set(i)).collect();
    // x +20 mm (524 288 counts) across +2³¹, y −20 mm across −2³¹, c +90° (327 680
    // counts) across +2³¹, d −90° (5833 counts) across −2³¹; then all go back.
    let there = [20.0, -20.0, 90.0, -90.0];
    for (leg, share) in [("across", 1.0), ("back", 0.0)] {
        let h: Vec<CommandHandle> = (0..4)
            .map(|i| {
                let to = p0[i] + share * there[i];
                let m = if i < 2 {
                    MovePtp::new(PositioningMode::AbsNormal, to)
                } else {
                    // The whole way, not the short way round the period.
                    MovePtp::new(PositioningMode::RelTarget, to - rig.unwrapped_set(i))
                };
                rig.command(i, Command::MovePtp(m))
            })
            .collect();
        rig.run_until(5000, leg, |r| h.iter().all(|h| r.done(h)));
        rig.settle(300);
        for i in 0..4 {
            let expect = share * there[i];
            let axis = &rig.drives[i].axis;
            let set = rig.unwrapped_set(i) - p0[i];
            assert!(
                (set - expect).abs() < 1e-6,
                "{leg}: axis {axis} set {set} from the start, expected {expect}"
            );
            let s = rig.kernel().axis_status(i).unwrap();
            let count = 1.0 / rig.scalings[i].counts_per_unit();
            assert!(
                (s.actual_position - s.set.p).abs() <= count,
                "{leg}: axis {axis} actual {} against set {}, more than a count",
                s.actual_position,
                s.set.p
            );
            let travelled = counter_difference(rig.counts(i), start[i]);
            let want = rig.travel_counts(i, expect);
            assert!(
                (travelled - want).abs() <= 2.0,
                "{leg}: drive {axis} travelled {travelled} counts, {expect} units is {want}"
            );
        }
    }
    rig.assert_invariants();
}
