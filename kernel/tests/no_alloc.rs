//! `Kernel::step` and command submission allocate nothing: a counting global allocator
//! watches this thread while 8 axes run S-curve moves, buffered moves, jogs and halts
//! for 20 000 cycles, and while a real axis runs homing (MoveHome and StepAbsoluteSwitch
//! against the axis model with its switches and latches) and hits a limit switch.

mod common;
mod homing_model;

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

#[test]
fn homing_runs_and_limit_switch_stops_do_not_allocate() {
    use gantry_kernel::axis::command::{Command, MoveDirection, MoveVelocity};
    use gantry_kernel::homing::{
        HomeDirection, HomingMode, MoveHome, MoveHomeCall, StepAbsoluteSwitch, SwitchConfig,
        SwitchMode,
    };
    use homing_model::{axis_config, Layout, Rig};

    let mut rig = Rig::new(axis_config(), Layout::STANDARD, 60.0);
    let home = MoveHome {
        direction: MoveDirection::Positive,
        switch_config: SwitchConfig::RefAndLimitSwitch,
        mode: HomingMode::ZeroPulse2Phase,
        acceleration: 250.0,
        jerk: 8_000.0,
        speed_switch_search: 25.0,
        max_distance_switch_search: 1_000.0,
        speed_reference_search: 2.5,
        max_distance_reference_search: 1_000.0,
        reference_offset: -4.0,
        normal_position: 0.0,
    };
    let step = StepAbsoluteSwitch {
        direction: HomeDirection::SwitchNegative,
        switch_mode: SwitchMode::EdgeSwitchPositive,
        position: 0.0,
        velocity: 20.0,
        acceleration: 200.0,
        deceleration: 200.0,
        jerk: 5_000.0,
        distance_limit: f64::INFINITY,
    };
    counting::watch(true);
    let mut cycles = 0u64;
    let h1 = rig.k.submit(0, Command::MoveHome(MoveHomeCall::all(home)));
    while !rig.k.command_status(h1).is_final() && cycles < 200_000 {
        rig.cycle();
        cycles += 1;
    }
    let h2 = rig.k.submit(0, Command::StepAbsoluteSwitch(step));
    while !rig.k.command_status(h2).is_final() && cycles < 400_000 {
        rig.cycle();
        cycles += 1;
    }
    // Into the positive limit switch: quick stop into ErrorStop.
    let h3 = rig.k.submit(
        0,
        Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 50.0)),
    );
    for _ in 0..10_000 {
        rig.cycle();
        cycles += 1;
    }
    counting::watch(false);
    let n = counting::take_count();
    assert_eq!(n, 0, "{n} allocations in {cycles} cycles");
    use gantry_kernel::axis::handle::CommandStatus;
    assert_eq!(rig.k.command_status(h1), CommandStatus::Done);
    assert_eq!(rig.k.command_status(h2), CommandStatus::Done);
    assert!(matches!(rig.k.command_status(h3), CommandStatus::Error(_)));
    assert!(cycles > 10_000);
}

#[test]
fn gears_cams_and_group_paths_do_not_allocate() {
    use gantry_kernel::axis::command::MoveVelocity;
    use gantry_kernel::axis::handle::CommandStatus;
    use gantry_kernel::cam::{CamPoint, CamTable, Interpolation};
    use gantry_kernel::group::run::{GroupCmd, GroupMove, GroupPathKind, Transition};
    use gantry_kernel::group::GroupConfig;
    use gantry_kernel::path::{CircMode, PathChoice, PathLimits};
    use gantry_kernel::sync::command::{CamIn, GearIn};
    let mut axes: Vec<_> = ["m", "g", "c", "x", "y"]
        .iter()
        .map(|n| linear(n))
        .collect();
    axes[0].kind = gantry_kernel::AxisKind::Virtual;
    let mut k = kernel(axes);
    for i in 3..5 {
        k.command(
            i,
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
        )
        .unwrap();
    }
    let table = CamTable::new(
        [(0.0, 0.0), (5.0, 1.0), (10.0, 0.0)]
            .iter()
            .map(|&(master, slave)| CamPoint { master, slave })
            .collect(),
        Interpolation::Cubic,
        true,
    )
    .unwrap();
    k.set_cam_table(0, Some(table)).unwrap();
    k.add_group(GroupConfig::new("xy", &[3, 4])).unwrap();
    let dynamics = PathLimits {
        v: 8.0,
        a: f64::INFINITY,
        d: f64::INFINITY,
        j: f64::INFINITY,
    };
    let line = |x: f64, y: f64| {
        GroupCmd::Move(GroupMove {
            path: GroupPathKind::Linear {
                target: [x, y, 0.0, 0.0],
            },
            relative: false,
            dynamics,
            buffer: BufferMode::Buffered,
            transition: Transition::None,
            corner_deviation: f64::INFINITY,
        })
    };
    counting::watch(true);
    let enable = k.group_command(0, GroupCmd::Enable);
    let gear = k.submit(1, Command::GearIn(GearIn::new(0, 2, 3)));
    let cam = k.submit(2, Command::CamIn(CamIn::new(0, 0, true)));
    let _ = k.submit(
        0,
        Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 5.0)),
    );
    let moves = [
        k.group_command(0, line(10.0, 0.0)),
        k.group_command(
            0,
            GroupCmd::Move(GroupMove {
                path: GroupPathKind::Circular {
                    circ: (0, 1),
                    aux: [10.0, 5.0],
                    end: [10.0, 10.0],
                    mode: CircMode::Center,
                    choice: PathChoice::Ccw,
                },
                relative: false,
                dynamics,
                buffer: BufferMode::Buffered,
                transition: Transition::None,
                corner_deviation: f64::INFINITY,
            }),
        ),
        k.group_command(0, line(0.0, 0.0)),
        // Blended behind: a corner superimposed, then a collinear junction.
        k.group_command(
            0,
            GroupCmd::Move(GroupMove {
                buffer: BufferMode::BlendingNext,
                transition: Transition::CornerSuperimposed,
                corner_deviation: 0.5,
                ..match line(0.0, 5.0) {
                    GroupCmd::Move(m) => m,
                    _ => unreachable!(),
                }
            }),
        ),
        k.group_command(
            0,
            GroupCmd::Move(GroupMove {
                buffer: BufferMode::BlendingLow,
                ..match line(0.0, 8.0) {
                    GroupCmd::Move(m) => m,
                    _ => unreachable!(),
                }
            }),
        ),
    ];
    for _ in 0..20_000 {
        k.step(&[]);
    }
    // Aborting a moving group, then a halt.
    let again = k.group_command(0, line(5.0, 5.0));
    for _ in 0..300 {
        k.step(&[]);
    }
    let abort = k.group_command(
        0,
        GroupCmd::Move(GroupMove {
            buffer: BufferMode::Aborting,
            ..match line(0.0, 0.0) {
                GroupCmd::Move(m) => m,
                _ => unreachable!(),
            }
        }),
    );
    for _ in 0..300 {
        k.step(&[]);
    }
    let halt = k.group_command(0, GroupCmd::Halt);
    for _ in 0..5000 {
        k.step(&[]);
    }
    assert_eq!(k.groups()[0].corners().blends, 2, "both junctions blended");
    let stop = k.group_command(0, GroupCmd::Stop);
    for _ in 0..100 {
        k.step(&[]);
    }
    counting::watch(false);
    let n = counting::take_count();
    assert_eq!(n, 0, "{n} allocations");
    assert!(enable.is_ok() && stop.is_ok());
    assert_eq!(
        k.command_status(again.unwrap()),
        CommandStatus::Aborted,
        "taken over by the Aborting move"
    );
    assert_eq!(
        k.command_status(abort.unwrap()),
        CommandStatus::Aborted,
        "taken over by the halt"
    );
    assert_eq!(k.command_status(halt.unwrap()), CommandStatus::Done);
    for h in moves {
        assert_eq!(k.command_status(h.unwrap()), CommandStatus::Done);
    }
    assert_eq!(k.command_status(gear), CommandStatus::Active);
    assert_eq!(k.command_status(cam), CommandStatus::Active);
}
