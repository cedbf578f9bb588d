//! Drive counts end to end (issue 10 §1): one-way modulo axes, through gantry's engine on
//! the lockstep rig (`gantry_tests::drive_counts`); the drives judge what reached them.

use gantry_drives::scaling::ScalingConfig;
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode};
use gantry_kernel::mechanics::Modulo;
use gantry_tests::drive_counts::{axis, scaling, AxisSpec, Machine};

/// One-way modulo axes (a conveyor, a ratchet): absolute moves go the allowed way round,
/// through the wrap, every time, and the drive only ever counts that way.
#[test]
fn positive_only_and_negative_only_modulo_axes_wrap_one_way() {
    let specs = vec![
        AxisSpec {
            direction: "positive",
            ..axis(
                "p",
                Some(360.0),
                720.0,
                scaling(10_000, 7, 3, 360.0),
                1_000_000,
            )
        },
        AxisSpec {
            direction: "negative",
            ..axis(
                "n",
                Some(360.0),
                720.0,
                ScalingConfig {
                    invert: true,
                    ..scaling(1 << 17, 10, 1, 360.0)
                },
                -7_777_777,
            )
        },
    ];
    let mut rig = Machine::new(specs);
    rig.enable_all();
    let start: Vec<f64> = (0..2).map(|i| rig.counts(i)).collect();
    let mut travelled = [0.0f64; 2];
    let mut from = [0, 1].map(|i| rig.kernel().axis_status(i).unwrap().set.p);
    for target in [90.0, 10.0, 300.0, 5.0, 359.0, 0.5, 180.0, 179.0] {
        let m = Modulo::new(360.0).unwrap();
        let handles = [
            rig.command(
                0,
                Command::MovePtp(MovePtp::new(PositioningMode::AbsModuloPos, target)),
            ),
            rig.command(
                1,
                Command::MovePtp(MovePtp::new(PositioningMode::AbsModuloNeg, target)),
            ),
        ];
        travelled[0] += m.delta_positive(from[0], target);
        travelled[1] += m.delta_negative(from[1], target);
        from = [target; 2];
        // The drive's position demand (the targets it got, interpolated) runs one way only;
        // the load follows it through a PI velocity loop, which may settle back by a
        // fraction of a count at the end of a move, as a real drive's does, never by one.
        let mut last: Vec<(f64, f64)> = (0..2).map(|i| (rig.demand(i), rig.counts(i))).collect();
        // p counts up as it turns positive; n is inverted, so its counts grow too as it
        // turns negative.
        rig.run_until(5000, "one-way move", |r| {
            for (i, last) in last.iter_mut().enumerate() {
                let (demand, c) = (r.demand(i), r.counts(i));
                assert!(
                    demand - last.0 >= 0.0,
                    "axis {i}: the drive's demand went back: {} → {demand}",
                    last.0
                );
                assert!(
                    c - last.1 > -1.0,
                    "axis {i}: the load counted back: {} → {c}",
                    last.1
                );
                *last = (demand, c);
            }
            handles.iter().all(|h| r.done(h))
        });
    }
    rig.settle(300);
    for i in 0..2 {
        let expect = rig.travel_counts(i, travelled[i]);
        let got = rig.counts(i) - start[i];
        assert!(
            (got - expect).abs() <= 2.0,
            "axis {}: drive travelled {got} counts, {}° is {expect}",
            rig.drives[i].axis,
            travelled[i]
        );
        assert!(travelled[i].abs() > 3.0 * 360.0, "{travelled:?}");
    }
    rig.assert_invariants();
}
