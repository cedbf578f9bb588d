//! Cost of `Kernel::step` per axis per cycle, for 1, 8 and 64 axes all running S-curve
//! PTP moves; and, as the baseline in the same run, the bare closed-form sampling of the
//! same profiles (what any kernel must at least do). The README reports both and their
//! ratio.

use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::profile::{plan_position, KinematicState, Limits, Profile, RampType};
use gantry_kernel::{AxisConfig, AxisKind, Kernel};

fn main() {
    divan::main();
}

const DT: f64 = 0.001;

fn limits(i: usize) -> Limits {
    Limits {
        vmax: 50.0 + i as f64,
        amax: 5.0 + (i % 7) as f64,
        dmax: 4.0 + (i % 5) as f64,
        jmax: 20.0 + (i % 3) as f64,
    }
}

/// A kernel whose `n` axes each run a long S-curve move (about 1000 s long, so the bench
/// samples acceleration, cruise and deceleration phases without replanning).
fn busy_kernel(n: usize) -> Kernel {
    let configs = (0..n)
        .map(|i| {
            let mut c = AxisConfig::new(&format!("a{i}"), AxisKind::Simulated);
            c.homing_required = false;
            c
        })
        .collect();
    let mut k = Kernel::new(DT, configs).expect("config");
    for i in 0..n {
        let l = limits(i);
        k.command(i, Command::Power(PowerCommand::Enable))
            .expect("enable");
        k.command(
            i,
            Command::MovePtp(
                MovePtp::new(PositioningMode::AbsNormal, 50_000.0 + 10.0 * i as f64)
                    .speed(l.vmax)
                    .accel(l.amax, l.dmax)
                    .jerk(l.jmax)
                    .ramp(RampType::SCurve),
            ),
        )
        .expect("move");
    }
    // Start somewhere inside the moves.
    for _ in 0..3_000 {
        k.step(&[]);
    }
    k
}

#[divan::bench(args = [1, 8, 64])]
fn step(bencher: divan::Bencher, n: usize) {
    let mut k = busy_kernel(n);
    bencher
        .counter(divan::counter::ItemsCount::new(n))
        .bench_local(|| {
            divan::black_box(k.step(&[]));
        });
}

#[divan::bench(args = [1, 8, 64])]
fn baseline_sample_only(bencher: divan::Bencher, n: usize) {
    let profiles: Vec<Profile> = (0..n)
        .map(|i| {
            plan_position(
                RampType::SCurve,
                KinematicState::at_rest(0.0),
                50_000.0 + 10.0 * i as f64,
                0.0,
                &limits(i),
            )
            .expect("plan")
        })
        .collect();
    let mut tick = 3_000u64;
    bencher
        .counter(divan::counter::ItemsCount::new(n))
        .bench_local(|| {
            tick += 1;
            let t = tick as f64 * DT;
            let mut acc = 0.0;
            for p in &profiles {
                acc += p.sample(t).p;
            }
            divan::black_box(acc);
        });
}
