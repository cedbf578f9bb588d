//! Drive counts end to end (issue 10 §1): SetPosition and enable with the drive's actual
//! outside one period, through gantry's engine on the lockstep rig
//! (`gantry_tests::drive_counts`); the drives judge what reached them.

use gantry::runtime::controller::CommandHandle;
use gantry_drives::scaling::ScalingConfig;
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode};
use gantry_kernel::mechanics::Modulo;
use gantry_tests::drive_counts::{axis, scaling, Machine, DT};

/// The user's report (issue 10 §1): the drive powers up 3.8 periods into its counter (and
/// another below zero); enable, `set-position c 350`, `move c --to 720 --mode relative
/// --speed 360`. Enabling must not move the drive, the move must be continuous in drive
/// counts — the drive travels exactly 720° = 2 621 440 counts — and `c.actual` never jumps
/// (it jumped 349.8° → 452.6° in one cycle).
#[test]
fn set_position_and_enable_with_the_actual_outside_one_period() {
    let specs = vec![
        axis(
            "c",
            Some(360.0),
            720.0,
            scaling(1 << 17, 10, 1, 360.0),
            5_000_000,
        ),
        axis(
            "d",
            Some(360.0),
            720.0,
            scaling(10_000, 7, 3, 360.0),
            -3_000_001,
        ),
        // Set to 350° while still disabled, then enabled.
        axis(
            "e",
            Some(360.0),
            720.0,
            ScalingConfig {
                invert: true,
                ..scaling(1 << 17, 10, 1, 360.0)
            },
            1_999_999_999,
        ),
    ];
    let mut rig = Machine::new(specs);
    rig.settle(3);
    rig.set_position(2, 350.0);
    rig.settle(3);
    let before: Vec<f64> = (0..3).map(|i| rig.counts(i)).collect();
    rig.enable_all();
    rig.settle(50);
    for (i, b) in before.iter().enumerate() {
        assert!(
            (rig.counts(i) - b).abs() < 1.0,
            "axis {}: enabling moved the drive from {b} to {} counts",
            rig.drives[i].axis,
            rig.counts(i)
        );
    }
    for i in 0..2 {
        rig.set_position(i, 350.0);
    }
    rig.settle(5);
    let start: Vec<f64> = (0..3).map(|i| rig.counts(i)).collect();
    let moves: Vec<CommandHandle> = (0..3)
        .map(|i| {
            rig.command(
                i,
                Command::MovePtp(MovePtp::new(PositioningMode::RelTarget, 720.0).speed(360.0)),
            )
        })
        .collect();
    let mut last_actual = [350.0f64; 3];
    let mut worst = [0.0f64; 3];
    rig.run_until(5000, "move 720°", |r| {
        for (i, (last, w)) in last_actual.iter_mut().zip(&mut worst).enumerate() {
            let a = r.kernel().axis_status(i).unwrap().actual_position;
            let m = Modulo::new(360.0).unwrap();
            *w = w.max(m.delta_shortest(m.wrap(*last), m.wrap(a)).abs());
            *last = a;
        }
        moves.iter().all(|h| r.done(h))
    });
    rig.settle(300);
    for i in 0..3 {
        let axis = &rig.drives[i].axis;
        assert!(
            worst[i] <= 360.0 * DT * 1.5,
            "axis {axis}: actual jumped {}° in one cycle",
            worst[i]
        );
        let expect = rig.travel_counts(i, 720.0);
        let got = rig.counts(i) - start[i];
        assert!(
            (got - expect).abs() <= 2.0,
            "axis {axis}: drive travelled {got} counts, 720° is {expect}"
        );
        let s = rig.kernel().axis_status(i).unwrap();
        assert!(
            (s.set.p - 350.0).abs() < 1e-9,
            "axis {axis}: set {}",
            s.set.p
        );
        assert!(
            (s.actual_position - 350.0).abs() < 0.01,
            "axis {axis}: actual {}",
            s.actual_position
        );
    }
    rig.assert_invariants();
}
