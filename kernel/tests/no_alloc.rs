//! `Kernel::step` and command submission allocate nothing: a counting global allocator
//! watches this thread while 8 axes run S-curve moves, buffered moves, jogs and halts
//! for 20 000 cycles.

mod common;

use common::*;
use gantry_kernel::axis::command::{
    BufferMode, Command, HaltMode, Jog, MoveDirection, MovePtp, PositioningMode,
};
use gantry_kernel::profile::RampType;

mod counting {
    include!("common/counting_alloc.rs");
}

#[global_allocator]
static ALLOC: counting::Counting = counting::Counting;

#[test]
fn step_and_commands_do_not_allocate() {
    let axes = (0..8)
        .map(|i| {
            let mut c = if i % 2 == 0 {
                linear(&format!("a{i}"))
            } else {
                rotary(&format!("a{i}"))
            };
            c.defaults.ramp = RampType::SCurve;
            c
        })
        .collect();
    let mut k = kernel(axes);
    counting::watch(true);
    let mut cycles = 0u64;
    for round in 0..40 {
        for axis in 0..8 {
            let target = ((round * 7 + axis * 3) % 50) as f64;
            let mode = if axis % 2 == 0 {
                PositioningMode::AbsNormal
            } else {
                PositioningMode::AbsModuloAuto
            };
            let _ = k.submit(axis, Command::MovePtp(MovePtp::new(mode, target)));
            let _ = k.submit(
                axis,
                Command::MovePtp(
                    MovePtp::new(PositioningMode::RelTarget, 5.0)
                        .buffered(BufferMode::BlendingNext),
                ),
            );
            if round % 5 == 3 {
                let _ = k.submit(
                    axis,
                    Command::Jog(Jog::new(MoveDirection::Positive, 3.0, 50.0, 50.0)),
                );
            }
            if round % 7 == 6 {
                let _ = k.submit(
                    axis,
                    Command::Halt {
                        mode: HaltMode::AtActualPosition,
                        deceleration: None,
                    },
                );
            }
        }
        for _ in 0..500 {
            k.step(&[]);
            cycles += 1;
        }
    }
    counting::watch(false);
    let n = counting::take_count();
    assert_eq!(n, 0, "{n} allocations in {cycles} cycles");
    assert_eq!(cycles, 20_000);
}
