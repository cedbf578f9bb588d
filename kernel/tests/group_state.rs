//! Axis groups before they move (PLCopen Part 4, seed 004 Omron NJ): the state table, the
//! commands each state takes, MC_GroupEnable's rules, a move's start rules, the handle
//! timing and the coordinated status.

use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_kernel::group::status::start_abort_cause;
use gantry_kernel::group::{
    accepts, check_enable, check_move_start, coordinated, enabled_group_of, next_status,
    start_status, AbortCause, AxisView, FbOutputs, GroupCommand, GroupCommandError, GroupConfig,
    GroupConfigError, GroupEnableError, GroupEvent, GroupMoveError, GroupState, HandleEvent,
    MoveView,
};
use gantry_kernel::homing::{LimitSide, SwitchInputs};
use gantry_kernel::AxisKind;

use GroupCommand as C;
use GroupEvent as E;
use GroupState as S;

/// Every transition the table holds; every other (state, event) pair is refused.
const TRANSITIONS: [(GroupState, GroupEvent, GroupState); 28] = [
    // MC_GroupEnable, and MC_GroupDisable as a no-op.
    (S::Disabled, E::Enabled, S::Standby),
    (S::Disabled, E::Disabled, S::Disabled),
    (S::Standby, E::Enabled, S::Standby),
    (S::Standby, E::Disabled, S::Disabled),
    (S::Standby, E::MoveStarted, S::Moving),
    (S::Standby, E::StopStarted, S::Stopping),
    (S::Standby, E::HomingStarted, S::Homing),
    (S::Standby, E::Error, S::ErrorStop),
    (S::Standby, E::Reset, S::Standby),
    (S::Homing, E::Disabled, S::Disabled),
    (S::Homing, E::StopStarted, S::Stopping),
    (S::Homing, E::HomingDone, S::Standby),
    (S::Homing, E::Error, S::ErrorStop),
    (S::Homing, E::Reset, S::Homing),
    (S::Moving, E::Disabled, S::Disabled),
    (S::Moving, E::MoveStarted, S::Moving),
    (S::Moving, E::MoveDone, S::Standby),
    (S::Moving, E::StopStarted, S::Stopping),
    (S::Moving, E::Error, S::ErrorStop),
    (S::Moving, E::Reset, S::Moving),
    (S::Stopping, E::Disabled, S::Disabled),
    (S::Stopping, E::StopReleased, S::Standby),
    (S::Stopping, E::Error, S::ErrorStop),
    (S::ErrorStop, E::Disabled, S::Disabled),
    (S::ErrorStop, E::Error, S::ErrorStop),
    (S::ErrorStop, E::StopStarted, S::ErrorStop),
    (S::ErrorStop, E::MoveDone, S::ErrorStop),
    (S::ErrorStop, E::Reset, S::Standby),
];

/// Every command each state takes; every other pair is refused.
const ACCEPTED: [(GroupState, &[GroupCommand]); 6] = [
    (S::Disabled, &[C::Enable, C::Disable]),
    (
        S::Standby,
        &[
            C::Enable,
            C::Disable,
            C::MoveLinear,
            C::MoveCircular2D,
            C::Stop,
            C::Halt,
            C::Home,
            C::Reset,
        ],
    ),
    (S::Homing, &[C::Disable, C::Stop, C::Reset]),
    (
        S::Moving,
        &[
            C::Disable,
            C::MoveLinear,
            C::MoveCircular2D,
            C::Stop,
            C::Halt,
            C::Reset,
        ],
    ),
    (S::Stopping, &[C::Disable, C::Release]),
    (S::ErrorStop, &[C::Disable, C::Reset]),
];

fn expected_transition(s: GroupState, e: GroupEvent) -> Option<GroupState> {
    TRANSITIONS
        .iter()
        .find(|&&(from, ev, _)| from == s && ev == e)
        .map(|&(_, _, to)| to)
}

fn expected_accepts(s: GroupState, c: GroupCommand) -> bool {
    ACCEPTED
        .iter()
        .any(|&(state, cmds)| state == s && cmds.contains(&c))
}

#[test]
fn the_table_holds_exactly_the_listed_transitions() {
    let mut taken = 0;
    for s in S::ALL {
        for e in E::ALL {
            assert_eq!(s.on(e), expected_transition(s, e), "{s:?} on {e:?}");
            taken += usize::from(s.on(e).is_some());
        }
    }
    assert_eq!(taken, TRANSITIONS.len());
    assert_eq!(S::ALL.len() * E::ALL.len() - taken, 32, "refused pairs");
}

#[test]
fn each_state_accepts_exactly_the_listed_commands() {
    for s in S::ALL {
        for c in C::ALL {
            assert_eq!(accepts(s, &c), expected_accepts(s, c), "{s:?} takes {c:?}");
        }
    }
}

#[test]
fn disable_leads_to_disabled_from_every_state_and_only_disable_enters_disabled() {
    // PLCopen Part 4: MC_GroupDisable can be issued in all states, also Stopping (it cancels
    // the stop) and ErrorStop.
    for s in S::ALL {
        assert!(accepts(s, &C::Disable), "{s:?}");
        assert_eq!(s.on(E::Disabled), Some(S::Disabled), "{s:?}");
        for e in E::ALL {
            if e != E::Disabled && s != S::Disabled {
                assert_ne!(s.on(e), Some(S::Disabled), "{s:?} on {e:?}");
            }
        }
    }
}

#[test]
fn only_reset_and_disable_leave_error_stop() {
    for e in E::ALL {
        let to = S::ErrorStop.on(e);
        let leaves = to.is_some_and(|t| t != S::ErrorStop);
        assert_eq!(
            leaves,
            matches!(e, E::Reset | E::Disabled),
            "{e:?} -> {to:?}"
        );
    }
    assert_eq!(S::ErrorStop.on(E::Reset), Some(S::Standby));
}

#[test]
fn an_error_stops_every_enabled_group_and_a_disabled_group_has_none() {
    for s in S::ALL {
        let expected = s.is_enabled().then_some(S::ErrorStop);
        assert_eq!(s.on(E::Error), expected, "{s:?}");
    }
}

#[test]
fn an_accepted_command_always_has_its_transition() {
    let event = |c: GroupCommand| match c {
        C::Enable => E::Enabled,
        C::Disable => E::Disabled,
        C::MoveLinear | C::MoveCircular2D | C::Halt => E::MoveStarted,
        C::Home => E::HomingStarted,
        C::Stop => E::StopStarted,
        C::Reset => E::Reset,
        C::Release => E::StopReleased,
    };
    for s in S::ALL {
        for c in C::ALL {
            if accepts(s, &c) {
                assert!(
                    s.on(event(c)).is_some(),
                    "{s:?} takes {c:?} but not its event"
                );
            }
        }
    }
}

#[test]
fn a_stop_locks_the_group_until_released() {
    for s in [S::Standby, S::Homing, S::Moving] {
        assert_eq!(s.on(E::StopStarted), Some(S::Stopping), "{s:?}");
    }
    for c in [C::MoveLinear, C::MoveCircular2D, C::Halt, C::Stop, C::Reset] {
        assert!(!accepts(S::Stopping, &c), "{c:?}");
    }
    assert_eq!(S::Stopping.on(E::MoveStarted), None);
    assert_eq!(S::Stopping.on(E::StopReleased), Some(S::Standby));
    assert_eq!(S::Standby.on(E::StopReleased), None);
}

#[test]
fn a_path_runs_from_standby_to_moving_and_back_and_homing_takes_no_path() {
    assert_eq!(S::Standby.on(E::MoveStarted), Some(S::Moving));
    assert_eq!(
        S::Moving.on(E::MoveStarted),
        Some(S::Moving),
        "aborting or buffered"
    );
    assert_eq!(S::Moving.on(E::MoveDone), Some(S::Standby));
    assert_eq!(S::Standby.on(E::MoveDone), None);
    assert_eq!(S::Standby.on(E::HomingStarted), Some(S::Homing));
    assert_eq!(S::Moving.on(E::HomingStarted), None);
    assert_eq!(S::Homing.on(E::HomingDone), Some(S::Standby));
    assert_eq!(S::Homing.on(E::MoveStarted), None);
    assert!(!accepts(S::Homing, &C::MoveLinear));
}

#[test]
fn state_and_command_names_are_plcopen_and_omron_function_blocks() {
    let names: Vec<_> = S::ALL.iter().map(|s| s.name()).collect();
    assert_eq!(
        names,
        [
            "GroupDisabled",
            "GroupStandby",
            "GroupHoming",
            "GroupMoving",
            "GroupStopping",
            "GroupErrorStop"
        ]
    );
    assert_eq!(C::Enable.name(), "MC_GroupEnable");
    assert_eq!(C::MoveCircular2D.name(), "MC_MoveCircular2D");
    assert_eq!(GroupState::default(), S::Disabled);
}

// --- configuration -----------------------------------------------------------------------

const KINDS: [AxisKind; 6] = [
    AxisKind::Real,
    AxisKind::Simulated,
    AxisKind::Virtual,
    AxisKind::External,
    AxisKind::Shadow { source: 0 },
    AxisKind::Real,
];

#[test]
fn a_group_of_one_to_four_distinct_motion_axes_is_valid() {
    for axes in [&[0][..], &[0, 1], &[2, 1, 0], &[5, 0, 1, 2]] {
        let g = GroupConfig::new("xy", axes);
        assert_eq!(g.validate(&KINDS), Ok(()), "{axes:?}");
    }
    let g = GroupConfig::new("xy", &[5, 0]);
    assert_eq!(g.logical(0), Some(1));
    assert_eq!(g.logical(3), None);
}

#[test]
fn configuration_errors_name_the_group_and_the_axis() {
    let cases: [(&[usize], GroupConfigError, &str); 6] = [
        (
            &[],
            GroupConfigError::NoAxes { group: "g".into() },
            "group g: no axes; a group has 1 to 4 axes (A0..A3)",
        ),
        (
            &[0, 1, 2, 5, 0],
            GroupConfigError::TooManyAxes {
                group: "g".into(),
                count: 5,
            },
            "group g: 5 axes; a group has 1 to 4 axes (A0..A3)",
        ),
        (
            &[0, 9],
            GroupConfigError::NoSuchAxis {
                group: "g".into(),
                logical: 1,
                axis: 9,
                configured: 6,
            },
            "group g: A1 is axis 9, but only 6 axes are configured",
        ),
        (
            &[1, 0, 1],
            GroupConfigError::DuplicateAxis {
                group: "g".into(),
                axis: 1,
                first: 0,
                second: 2,
            },
            "group g: axis 1 is both A0 and A2",
        ),
        (
            &[0, 3],
            GroupConfigError::AxisKindNotSupported {
                group: "g".into(),
                logical: 1,
                axis: 3,
                kind: "external",
            },
            "group g: A1 is axis 3 of type external; a group takes only real, simulated and \
             virtual axes (Omron 543D: axis type not supported)",
        ),
        (
            &[4],
            GroupConfigError::AxisKindNotSupported {
                group: "g".into(),
                logical: 0,
                axis: 4,
                kind: "shadow",
            },
            "group g: A0 is axis 4 of type shadow; a group takes only real, simulated and \
             virtual axes (Omron 543D: axis type not supported)",
        ),
    ];
    for (axes, err, msg) in cases {
        let got = GroupConfig::new("g", axes).validate(&KINDS);
        assert_eq!(got.as_ref(), Err(&err), "{axes:?}");
        assert_eq!(err.to_string(), msg);
    }
}

// --- MC_GroupEnable ----------------------------------------------------------------------

fn view(state: AxisState, kind: AxisKind) -> AxisView {
    AxisView {
        state,
        kind,
        homed: true,
        in_enabled_group: None,
    }
}

fn axes() -> Vec<AxisView> {
    KINDS
        .iter()
        .map(|&k| view(AxisState::Standstill, k))
        .collect()
}

#[test]
fn enable_takes_axes_that_are_disabled_or_at_standstill_homed_or_not() {
    let g = GroupConfig::new("xy", &[0, 1, 2]);
    let mut a = axes();
    assert_eq!(check_enable(&g, &a), Ok(()));
    a[0].state = AxisState::Disabled;
    a[1].homed = false;
    // An axis in an enabled group that is not this group's concerns nobody.
    a[5].in_enabled_group = Some(3);
    assert_eq!(check_enable(&g, &a), Ok(()));
}

#[test]
fn enable_refuses_axes_that_move_or_stop_or_are_in_error() {
    let g = GroupConfig::new("xy", &[0, 1]);
    for state in [
        AxisState::Homing,
        AxisState::DiscreteMotion,
        AxisState::ContinuousMotion,
        AxisState::SynchronizedMotion,
        AxisState::Stopping,
        AxisState::ErrorStop,
    ] {
        let mut a = axes();
        a[1].state = state;
        let err = GroupEnableError::NotStandingStill {
            logical: 1,
            axis: 1,
            state,
        };
        assert_eq!(check_enable(&g, &a), Err(err), "{state:?}");
        assert_eq!(
            err.to_string(),
            format!(
                "MC_GroupEnable: A1 (axis 1) is in {}; every axis of the group must be \
                 Disabled or at Standstill",
                state.name()
            )
        );
    }
}

#[test]
fn enable_refuses_an_axis_of_another_enabled_group_naming_both() {
    let g = GroupConfig::new("xy", &[5, 2]);
    let mut a = axes();
    a[2].in_enabled_group = Some(1);
    let err = GroupEnableError::InOtherGroup {
        logical: 1,
        axis: 2,
        other: 1,
    };
    assert_eq!(check_enable(&g, &a), Err(err));
    assert_eq!(
        err.to_string(),
        "MC_GroupEnable: A1 (axis 2) belongs to enabled group 1; an axis can be in one enabled \
         group only"
    );
}

#[test]
fn enable_refuses_axes_that_take_no_motion() {
    for (axis, kind) in [(3, "external"), (4, "shadow")] {
        let g = GroupConfig::new("xy", &[0, axis]);
        let err = GroupEnableError::KindNotSupported {
            logical: 1,
            axis,
            kind,
        };
        assert_eq!(check_enable(&g, &axes()), Err(err));
        assert_eq!(
            err.to_string(),
            format!(
                "MC_GroupEnable: A1 is axis {axis} of type {kind}; a group takes only real, \
                 simulated and virtual axes (Omron 543D: axis type not supported)"
            )
        );
    }
}

#[test]
fn enable_refuses_missing_axes_and_empty_or_oversized_groups() {
    let g = GroupConfig::new("xy", &[0, 7]);
    let err = GroupEnableError::NoSuchAxis {
        logical: 1,
        axis: 7,
    };
    assert_eq!(check_enable(&g, &axes()), Err(err));
    assert_eq!(
        err.to_string(),
        "MC_GroupEnable: A1 is axis 7, which does not exist"
    );
    for (list, count) in [(&[][..], 0), (&[0, 1, 2, 5, 0][..], 5)] {
        let err = GroupEnableError::AxisCount { count };
        assert_eq!(
            check_enable(&GroupConfig::new("g", list), &axes()),
            Err(err)
        );
        assert_eq!(
            err.to_string(),
            format!("MC_GroupEnable: the group has {count} axes; a group has 1 to 4 axes (A0..A3)")
        );
    }
}

#[test]
fn enable_reports_the_first_logical_axis_that_breaks_a_rule() {
    let g = GroupConfig::new("xy", &[1, 0]);
    let mut a = axes();
    a[0].state = AxisState::ErrorStop;
    a[1].in_enabled_group = Some(2);
    assert_eq!(
        check_enable(&g, &a),
        Err(GroupEnableError::InOtherGroup {
            logical: 0,
            axis: 1,
            other: 2
        })
    );
}

// --- a move's start ----------------------------------------------------------------------

fn mv(axis: usize) -> MoveView {
    MoveView {
        axis,
        homed: true,
        switches: SwitchInputs::default(),
    }
}

#[test]
fn a_move_starts_when_every_axis_is_homed_and_no_limit_is_on() {
    let mut a = [mv(4), mv(2), mv(7)];
    a[1].switches.reference = true; // the reference switch does not stop a path
    assert_eq!(check_move_start(&a), Ok(()));
    assert_eq!(check_move_start(&[]), Ok(()));
}

#[test]
fn a_move_refuses_an_axis_not_homed_omron_5466() {
    let mut a = [mv(4), mv(2), mv(7)];
    a[2].homed = false;
    let err = GroupMoveError::NotHomed {
        logical: 2,
        axis: 7,
    };
    assert_eq!(check_move_start(&a), Err(err));
    assert_eq!(
        err.to_string(),
        "A2 (axis 7) is not homed; a group move needs every axis of the group homed (Omron \
         5466: command started with the home not defined)"
    );
}

#[test]
fn a_move_refuses_an_active_limit_input_on_any_axis_of_the_group() {
    for (negative, positive, side) in [
        (true, false, LimitSide::Negative),
        (false, true, LimitSide::Positive),
    ] {
        let mut a = [mv(4), mv(2), mv(7), mv(0)];
        a[3].switches.negative_limit = negative;
        a[3].switches.positive_limit = positive;
        let err = GroupMoveError::LimitSwitchActive {
            logical: 3,
            axis: 0,
            side,
        };
        assert_eq!(check_move_start(&a), Err(err));
        assert_eq!(
            err.to_string(),
            format!(
                "A3 (axis 0): the {} limit switch is active; a group move does not start while \
                 a limit input of any axis of the group is on",
                side.name()
            )
        );
    }
}

#[test]
fn a_missing_home_is_reported_before_a_limit_input() {
    let mut a = [mv(4), mv(2)];
    a[0].switches.positive_limit = true;
    a[1].homed = false;
    assert_eq!(
        check_move_start(&a),
        Err(GroupMoveError::NotHomed {
            logical: 1,
            axis: 2
        })
    );
}

// --- handle timing -----------------------------------------------------------------------

#[test]
fn a_command_starts_busy_where_it_is_taken_and_its_conditions_hold() {
    for s in S::ALL {
        for c in C::ALL {
            let got = start_status(s, c, || Ok(()));
            let expected = if accepts(s, &c) {
                Ok(CommandStatus::Busy)
            } else if c.is_motion() && matches!(s, S::ErrorStop | S::Stopping) {
                Ok(CommandStatus::Aborted)
            } else {
                Err(GroupCommandError::NotAllowedInState {
                    command: c.name(),
                    state: s,
                })
            };
            assert_eq!(got, expected, "{c:?} in {s:?}");
        }
    }
}

#[test]
fn moves_started_in_error_or_while_stopping_end_command_aborted_seed_004() {
    for c in [C::MoveLinear, C::MoveCircular2D, C::Halt] {
        assert_eq!(
            start_status(S::ErrorStop, c, || Ok(())),
            Ok(CommandStatus::Aborted)
        );
        assert_eq!(
            start_abort_cause(S::ErrorStop, c),
            Some(AbortCause::StartedInErrorStop)
        );
        assert_eq!(
            start_status(S::Stopping, c, || Ok(())),
            Ok(CommandStatus::Aborted)
        );
        assert_eq!(
            start_abort_cause(S::Stopping, c),
            Some(AbortCause::StartedWhileStopping)
        );
        // A disabled group is an error of the start conditions, not an abort.
        let err = start_status(S::Disabled, c, || Ok(())).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!("{} is not allowed in state GroupDisabled", c.name())
        );
        assert_eq!(start_abort_cause(S::Disabled, c), None);
        assert_eq!(start_abort_cause(S::Standby, c), None);
    }
    // Administrative commands refused in ErrorStop are errors.
    assert_eq!(
        start_status(S::ErrorStop, C::Enable, || Ok(())),
        Err(GroupCommandError::NotAllowedInState {
            command: "MC_GroupEnable",
            state: S::ErrorStop
        })
    );
}

#[test]
fn broken_start_conditions_are_the_handles_error_and_run_only_when_the_state_takes_it() {
    let enable = GroupEnableError::InOtherGroup {
        logical: 0,
        axis: 3,
        other: 1,
    };
    let got = start_status(S::Disabled, C::Enable, || Err(enable.into()));
    assert_eq!(got, Err(GroupCommandError::Enable(enable)));
    assert_eq!(
        got.unwrap_err().to_string(),
        "MC_GroupEnable: A0 (axis 3) belongs to enabled group 1; an axis can be in one enabled \
         group only"
    );
    let error = GroupMoveError::NotHomed {
        logical: 1,
        axis: 4,
    };
    let move_err = GroupCommandError::MoveStart {
        command: C::MoveLinear.name(),
        error,
    };
    assert_eq!(
        start_status(S::Moving, C::MoveLinear, || Err(move_err)),
        Err(move_err)
    );
    assert!(move_err
        .to_string()
        .starts_with("MC_MoveLinear: A1 (axis 4) is not homed"));
    let mut ran = false;
    let got = start_status(S::ErrorStop, C::MoveLinear, || {
        ran = true;
        Err(move_err)
    });
    assert_eq!(got, Ok(CommandStatus::Aborted));
    assert!(!ran, "conditions are not checked when the state refuses");
}

#[test]
fn handle_goes_busy_active_done_and_final_status_sticks() {
    let mut s = CommandStatus::Busy;
    s = next_status(s, HandleEvent::AxesMoving);
    assert_eq!(s, CommandStatus::Active);
    s = next_status(s, HandleEvent::AxesMoving);
    assert_eq!(s, CommandStatus::Active);
    s = next_status(s, HandleEvent::Finished);
    assert_eq!(s, CommandStatus::Done);
    for e in [
        HandleEvent::AxesMoving,
        HandleEvent::Finished,
        HandleEvent::Aborted(AbortCause::GroupError),
    ] {
        assert_eq!(next_status(CommandStatus::Done, e), CommandStatus::Done);
        assert_eq!(
            next_status(CommandStatus::Aborted, e),
            CommandStatus::Aborted
        );
        assert_eq!(
            next_status(CommandStatus::Expired, e),
            CommandStatus::Expired
        );
    }
    // An administrative command (enable) is Done without moving anything.
    assert_eq!(
        next_status(CommandStatus::Busy, HandleEvent::Finished),
        CommandStatus::Done
    );
}

#[test]
fn every_abort_cause_ends_a_busy_or_active_handle_command_aborted() {
    for cause in [
        AbortCause::Command,
        AbortCause::GroupError,
        AbortCause::GroupStop,
        AbortCause::GroupDisable,
        AbortCause::StartedInErrorStop,
        AbortCause::StartedWhileStopping,
    ] {
        for s in [CommandStatus::Busy, CommandStatus::Active] {
            assert_eq!(
                next_status(s, HandleEvent::Aborted(cause)),
                CommandStatus::Aborted,
                "{s:?} {cause:?}"
            );
        }
    }
}

#[test]
fn output_bits_follow_the_seed_timing_chart() {
    let busy = FbOutputs::of(&CommandStatus::Busy, true, 0);
    assert_eq!(
        busy,
        FbOutputs {
            busy: true,
            ..FbOutputs::default()
        }
    );
    let active = FbOutputs::of(&CommandStatus::Active, true, 0);
    assert!(active.busy && active.active && !active.done);
    // Done stays while Execute is TRUE ...
    for cycles in [0, 1, 100] {
        let o = FbOutputs::of(&CommandStatus::Done, true, cycles);
        assert_eq!(
            o,
            FbOutputs {
                done: true,
                ..FbOutputs::default()
            }
        );
    }
    // ... and with Execute FALSE it is TRUE for the one cycle it arrives in.
    assert!(FbOutputs::of(&CommandStatus::Done, false, 0).done);
    assert!(!FbOutputs::of(&CommandStatus::Done, false, 1).done);
    assert!(FbOutputs::of(&CommandStatus::Aborted, true, 5).command_aborted);
    assert!(FbOutputs::of(&CommandStatus::Aborted, false, 0).command_aborted);
    assert_eq!(
        FbOutputs::of(&CommandStatus::Aborted, false, 1),
        FbOutputs::default()
    );
    let err = gantry_kernel::axis::command::CommandError::NoSuchAxis { axis: 0 };
    let o = FbOutputs::of(&CommandStatus::Error(err), false, 50);
    assert_eq!(
        o,
        FbOutputs {
            error: true,
            ..FbOutputs::default()
        },
        "Error holds until cleared, Busy and Active drop with it"
    );
    assert_eq!(
        FbOutputs::of(&CommandStatus::Expired, true, 0),
        FbOutputs::default()
    );
}

// --- coordinated -------------------------------------------------------------------------

#[test]
fn an_axis_is_coordinated_while_its_group_is_enabled_error_stop_included() {
    let xy = GroupConfig::new("xy", &[0, 1]);
    let zw = GroupConfig::new("zw", &[1, 2]);
    for s in S::ALL {
        let groups = [(&xy, s), (&zw, S::Disabled)];
        assert_eq!(coordinated(0, groups), s != S::Disabled, "{s:?}");
        assert_eq!(
            enabled_group_of(1, groups),
            (s != S::Disabled).then_some(0),
            "{s:?}"
        );
        assert!(!coordinated(2, groups));
        assert!(!coordinated(9, groups));
    }
    let groups = [(&xy, S::Disabled), (&zw, S::Moving)];
    assert_eq!(enabled_group_of(1, groups), Some(1));
    assert!(!coordinated(0, groups));
}

#[test]
fn enabled_group_of_feeds_the_enable_rule() {
    // Group 0 (xy) is enabled; enabling zw, which shares axis 1, is refused naming group 0.
    let xy = GroupConfig::new("xy", &[0, 1]);
    let zw = GroupConfig::new("zw", &[2, 1]);
    let groups = [(&xy, S::Standby), (&zw, S::Disabled)];
    let views: Vec<AxisView> = (0..3)
        .map(|i| AxisView {
            in_enabled_group: enabled_group_of(i, groups),
            ..view(AxisState::Standstill, AxisKind::Virtual)
        })
        .collect();
    assert_eq!(
        check_enable(&zw, &views),
        Err(GroupEnableError::InOtherGroup {
            logical: 1,
            axis: 1,
            other: 0
        })
    );
}
