//! MC_GroupHome (PLCopen Part 4; Omron has none): two real axes, each with its own
//! switches and encoder (the homing tests' axis model), home together — the group in
//! GroupHoming until both are homed, then GroupStandby and ready for a path; an axis whose
//! run fails puts the group in GroupErrorStop and halts the other; MC_GroupStop halts the
//! runs and is Done once the axes stand; moves are refused while the group homes.

mod homing_model;

use gantry_kernel::axis::command::{Command, CommandError, MoveDirection, PowerCommand};
use gantry_kernel::axis::handle::{CommandStatus, HandleId};
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::group::run::{BufferMode, GroupCmd, GroupMove, GroupPathKind, Transition};
use gantry_kernel::group::{GroupCommandError, GroupConfig, GroupState};
use gantry_kernel::homing::{HomingMode, MoveHome, SwitchConfig};
use gantry_kernel::path::PathLimits;
use gantry_kernel::Kernel;
use homing_model::{axis_config, AxisModel, Layout, ProbeSource, DT};

/// Each axis' saved homing run: towards `direction`, on the reference cam's edge.
fn saved(direction: MoveDirection) -> MoveHome {
    MoveHome {
        direction,
        switch_config: SwitchConfig::RefAndLimitSwitch,
        mode: HomingMode::SwitchingEdge2Phase,
        ..MoveHome::defaults(100.0, 1000.0, 20_000.0)
    }
}

/// Two real axes x (from -50) and y (from 60) with their models, group `xy`, enabled.
struct Rig {
    k: Kernel,
    m: [AxisModel; 2],
}

impl Rig {
    fn new(y_saved: MoveHome) -> Self {
        let mut x = axis_config();
        x.move_home = Some(saved(MoveDirection::Positive));
        x.initial_position = -50.0;
        let mut y = axis_config();
        y.name = "y".into();
        y.move_home = Some(y_saved);
        y.initial_position = 60.0;
        let mut k = Kernel::new(DT, vec![x, y]).unwrap();
        let mut m = [
            AxisModel::new(Layout::STANDARD, -50.0),
            AxisModel::new(Layout::STANDARD, 60.0),
        ];
        for mm in &mut m {
            mm.probe_source = ProbeSource::Reference;
        }
        for i in 0..2 {
            k.command(i, Command::Power(PowerCommand::Enable)).unwrap();
        }
        let mut rig = Self { k, m };
        for _ in 0..3 {
            rig.cycle();
        }
        rig.k.add_group(GroupConfig::new("xy", &[0, 1])).unwrap();
        rig.k.group_command(0, GroupCmd::Enable).unwrap();
        rig
    }

    fn cycle(&mut self) {
        let fb = [self.m[0].feedback(), self.m[1].feedback()];
        let sp = self.k.step(&fb).to_vec();
        for (m, sp) in self.m.iter_mut().zip(&sp) {
            m.advance(sp);
        }
    }

    /// Cycles until `h` is final (at most 100 s); the group states seen on the way.
    fn until_final(&mut self, h: HandleId) -> (CommandStatus, Vec<GroupState>) {
        let mut seen = Vec::new();
        for _ in 0..100_000 {
            self.cycle();
            let s = self.k.groups()[0].state();
            if seen.last() != Some(&s) {
                seen.push(s);
            }
            let st = self.k.command_status(h);
            if st.is_final() {
                return (st, seen);
            }
        }
        (self.k.command_status(h), seen)
    }
}

fn line(x: f64, y: f64) -> GroupCmd {
    GroupCmd::Move(GroupMove {
        path: GroupPathKind::Linear {
            target: [x, y, 0.0, 0.0],
        },
        relative: false,
        dynamics: PathLimits {
            v: 20.0,
            a: f64::INFINITY,
            d: f64::INFINITY,
            j: f64::INFINITY,
        },
        buffer: BufferMode::Aborting,
        transition: Transition::None,
        corner_deviation: f64::INFINITY,
    })
}

#[test]
fn both_axes_home_together_and_the_group_is_ready_for_a_path() {
    let mut rig = Rig::new(saved(MoveDirection::Negative));
    // Not homed: a path is refused, naming the rule.
    let e = rig.k.group_command(0, line(0.0, 0.0)).unwrap_err();
    assert!(e.to_string().contains("homed"), "{e}");
    let h = rig.k.group_command(0, GroupCmd::Home).unwrap();
    assert_eq!(rig.k.command_status(h), CommandStatus::Active);
    assert_eq!(rig.k.groups()[0].state(), GroupState::Homing);
    for i in 0..2 {
        assert_eq!(rig.k.axis_status(i).unwrap().state, AxisState::Homing);
    }
    // While homing: no path, no halt, no second homing.
    for cmd in [line(0.0, 0.0), GroupCmd::Halt, GroupCmd::Home] {
        let e = rig.k.group_command(0, cmd).unwrap_err();
        assert!(
            matches!(
                e,
                CommandError::Group(GroupCommandError::NotAllowedInState {
                    state: GroupState::Homing,
                    ..
                })
            ),
            "{e}"
        );
    }
    let (st, seen) = rig.until_final(h);
    assert_eq!(st, CommandStatus::Done);
    assert_eq!(seen.last(), Some(&GroupState::Standby));
    assert!(seen
        .iter()
        .all(|s| matches!(s, GroupState::Homing | GroupState::Standby)));
    for i in 0..2 {
        let s = rig.k.axis_status(i).unwrap();
        assert!(s.bits.homed, "axis {i}");
        assert_eq!(s.state, AxisState::Standstill);
    }
    // Ready: a path to (5, 5) runs and ends there.
    let m = rig.k.group_command(0, line(5.0, 5.0)).unwrap();
    let (st, _) = rig.until_final(m);
    assert_eq!(st, CommandStatus::Done);
    for i in 0..2 {
        assert!((rig.k.axis_status(i).unwrap().set.p - 5.0).abs() < 1e-9);
    }
}

#[test]
fn a_failed_run_puts_the_group_in_error_stop_and_halts_the_other_axis() {
    // y searches its cam within 5 mm only: its run ends in an error.
    let mut short = saved(MoveDirection::Negative);
    short.max_distance_switch_search = 5.0;
    let mut rig = Rig::new(short);
    let h = rig.k.group_command(0, GroupCmd::Home).unwrap();
    let (st, _) = rig.until_final(h);
    let CommandStatus::Error(e) = st else {
        panic!("{st:?}");
    };
    assert_eq!(
        e,
        CommandError::Group(GroupCommandError::HomingFailed {
            axis: 1,
            how: "in an error"
        })
    );
    assert!(
        e.to_string()
            .contains("axis 1's homing run ended in an error"),
        "{e}"
    );
    assert_eq!(rig.k.groups()[0].state(), GroupState::ErrorStop);
    // x was halted, not left homing; the group's error did not fault it.
    for _ in 0..2000 {
        rig.cycle();
    }
    let x = rig.k.axis_status(0).unwrap();
    assert_eq!(x.state, AxisState::Standstill, "{x:?}");
    assert!(!x.bits.homed);
    assert_eq!(x.set.v, 0.0);
    // GroupReset leaves ErrorStop.
    rig.k.group_command(0, GroupCmd::Reset).unwrap();
    assert_eq!(rig.k.groups()[0].state(), GroupState::Standby);
}

#[test]
fn a_stop_halts_the_runs_and_is_done_once_the_axes_stand() {
    let mut rig = Rig::new(saved(MoveDirection::Negative));
    let h = rig.k.group_command(0, GroupCmd::Home).unwrap();
    for _ in 0..200 {
        rig.cycle();
    }
    assert!(
        rig.k.axis_status(0).unwrap().set.v.abs() > 1.0,
        "x on its way"
    );
    let stop = rig.k.group_command(0, GroupCmd::Stop).unwrap();
    assert_eq!(rig.k.command_status(h), CommandStatus::Aborted);
    assert_eq!(rig.k.command_status(stop), CommandStatus::Active);
    assert_eq!(rig.k.groups()[0].state(), GroupState::Stopping);
    let (st, _) = rig.until_final(stop);
    assert_eq!(st, CommandStatus::Done);
    for i in 0..2 {
        let s = rig.k.axis_status(i).unwrap();
        assert_eq!(s.set.v, 0.0, "axis {i} stands");
        assert!(!s.bits.homed);
    }
    assert_eq!(rig.k.groups()[0].state(), GroupState::Stopping, "locked");
    rig.k.group_command(0, GroupCmd::Release).unwrap();
    assert_eq!(rig.k.groups()[0].state(), GroupState::Standby);
}
