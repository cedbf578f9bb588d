//! Jetter MoveHome (seed 000 §6.3.2): controller-side homing with a reference switch,
//! limit switches and the encoder's zero pulse, one or two phases.
//!
//! The reference edge is always the end of the switch cam facing *against* the search
//! direction (the first edge a search starting on the near side meets); a two-phase run
//! finds the cam fast, then crosses that edge slowly. With `ZeroPulse` and a switch, the
//! reference is the first index pulse beyond that edge, reached leaving the cam against
//! the search direction — the way CiA 402 homing methods 1–14 define it — so the result does
//! not depend on where the run started.

use super::inputs::LimitSide;
use super::sequence::{Finish, Goal, Marks, Plan, Search, Side, Signal, Start};
use crate::axis::command::MoveDirection;

/// Which switches the run uses (Jetter `ReferencingSwitchConfigs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SwitchConfig {
    /// Zero pulse only.
    NoSwitch,
    /// Reference switch; a limit switch reached during the search reverses it.
    RefAndLimitSwitch,
    /// Reference switch only (rotary axes, no limit switches): a limit switch is an error.
    RefSwitch,
    /// The limit switch in the search direction is the reference switch.
    LimitSwitch,
}

/// What the reference is and how many phases find it (Jetter `ReferencingModes`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HomingMode {
    /// Zero pulse, slow search only.
    ZeroPulse1Phase,
    /// Zero pulse: fast search, then slow search.
    ZeroPulse2Phase,
    /// Switch edge, slow search only.
    SwitchingEdge1Phase,
    /// Switch edge: fast search for the switch, then slow search for its edge.
    SwitchingEdge2Phase,
}

/// MoveHome's parameters (seed 000 §6.3.2.1). A call leaves out what it does not change
/// ([`MoveHomeCall`]); the axis keeps the last-used set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MoveHome {
    /// Search direction.
    pub direction: MoveDirection,
    /// Switches used.
    pub switch_config: SwitchConfig,
    /// Mode.
    pub mode: HomingMode,
    /// Acceleration and deceleration of every homing move (units/s², > 0).
    pub acceleration: f64,
    /// Jerk of every homing move (units/s³, > 0): homing moves are S-curves.
    pub jerk: f64,
    /// Speed of the coarse (first of two) phase (units/s, > 0).
    pub speed_switch_search: f64,
    /// Farthest the coarse phase may travel (units, > 0).
    pub max_distance_switch_search: f64,
    /// Speed of the fine (or only) phase (units/s, > 0).
    pub speed_reference_search: f64,
    /// Farthest the fine phase may travel (units, > 0).
    pub max_distance_reference_search: f64,
    /// Where the axis ends, relative to the reference found (units, signed).
    pub reference_offset: f64,
    /// The position the axis has when it stands there (units).
    pub normal_position: f64,
}

impl MoveHome {
    /// Defaults for an axis with maximum speed `vmax`, acceleration `amax` and jerk
    /// `jmax`: positive, RefAndLimitSwitch, SwitchingEdge2Phase, coarse at vmax/4, fine at
    /// vmax/40, unlimited distances, offset 0, NormalPosition 0, acceleration amax/2, jerk
    /// jmax/2 (half the maxima so the homing moves stay well inside them).
    pub fn defaults(vmax: f64, amax: f64, jmax: f64) -> Self {
        Self {
            direction: MoveDirection::Positive,
            switch_config: SwitchConfig::RefAndLimitSwitch,
            mode: HomingMode::SwitchingEdge2Phase,
            acceleration: amax / 2.0,
            jerk: jmax / 2.0,
            speed_switch_search: vmax / 4.0,
            max_distance_switch_search: f64::INFINITY,
            speed_reference_search: vmax / 40.0,
            max_distance_reference_search: f64::INFINITY,
            reference_offset: 0.0,
            normal_position: 0.0,
        }
    }

    /// The searches and finish of this run.
    pub fn plan(&self) -> Plan {
        let d = self.direction.sign();
        let signal = match self.switch_config {
            SwitchConfig::LimitSwitch => Signal::Limit(LimitSide::towards(d)),
            _ => Signal::Reference,
        };
        // The cam's end facing against the search direction.
        let side = if d > 0.0 { Side::Low } else { Side::High };
        let fast = |goal, start, marks| Search {
            goal,
            speed: self.speed_switch_search,
            max_distance: self.max_distance_switch_search,
            distance_name: "MaxDistanceSwitchSearch",
            start,
            marks,
        };
        let slow = |goal, start, marks| Search {
            goal,
            speed: self.speed_reference_search,
            max_distance: self.max_distance_reference_search,
            distance_name: "MaxDistanceReferenceSearch",
            start,
            marks,
        };
        let none = Marks {
            switch_found: false,
            reference_found: false,
        };
        let switch = Marks {
            switch_found: true,
            reference_found: false,
        };
        let reference = Marks {
            switch_found: false,
            reference_found: true,
        };
        let both = Marks {
            switch_found: true,
            reference_found: true,
        };
        let level = Goal::Level { signal, on: true };
        let index = |a: f64| Goal::Index {
            approach: Some(a),
            from_found: false,
        };
        let index_beyond = |a: f64| Goal::Index {
            approach: Some(a),
            from_found: true,
        };
        let with_switch = self.switch_config != SwitchConfig::NoSwitch;
        let searches = match (self.mode, with_switch) {
            (HomingMode::ZeroPulse1Phase, false) => {
                [Some(slow(index(d), Start::Toward(d), both)), None, None]
            }
            (HomingMode::ZeroPulse2Phase, false) => [
                Some(fast(index(d), Start::Toward(d), switch)),
                Some(slow(index_beyond(-d), Start::Back, reference)),
                None,
            ],
            (HomingMode::ZeroPulse1Phase, true) => [
                Some(slow(
                    Goal::Edge {
                        signal,
                        side,
                        approach: Some(-d),
                    },
                    Start::LeaveThen(d),
                    switch,
                )),
                Some(slow(index_beyond(-d), Start::Keep, reference)),
                None,
            ],
            (HomingMode::ZeroPulse2Phase, true) => [
                Some(fast(level, Start::Toward(d), switch)),
                Some(slow(
                    Goal::Edge {
                        signal,
                        side,
                        approach: Some(-d),
                    },
                    Start::Back,
                    none,
                )),
                Some(slow(index_beyond(-d), Start::Keep, reference)),
            ],
            // SwitchingEdge without a switch is refused by validation; plan it as a
            // zero-pulse run rather than panic.
            (HomingMode::SwitchingEdge1Phase, false) | (HomingMode::SwitchingEdge2Phase, false) => {
                [Some(slow(index(d), Start::Toward(d), both)), None, None]
            }
            (HomingMode::SwitchingEdge1Phase, true) => [
                Some(slow(
                    Goal::Edge {
                        signal,
                        side,
                        approach: None,
                    },
                    Start::LeaveThen(d),
                    both,
                )),
                None,
                None,
            ],
            (HomingMode::SwitchingEdge2Phase, true) => [
                Some(fast(level, Start::Toward(d), switch)),
                Some(slow(
                    Goal::Edge {
                        signal,
                        side,
                        approach: None,
                    },
                    Start::Back,
                    reference,
                )),
                None,
            ],
        };
        Plan {
            command: "MoveHome",
            searches,
            reverse_at_limits: self.switch_config == SwitchConfig::RefAndLimitSwitch,
            finish: Finish::MoveTo {
                offset: self.reference_offset,
                normal_position: self.normal_position,
            },
            direction: d,
        }
    }
}

/// A MoveHome call: every parameter optional; left-out ones keep the axis' last-used value
/// (seed 000 §6.3.2: "all parameters of the call are optional").
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MoveHomeCall {
    /// Search direction.
    pub direction: Option<MoveDirection>,
    /// Switches used.
    pub switch_config: Option<SwitchConfig>,
    /// Mode.
    pub mode: Option<HomingMode>,
    /// Acceleration (units/s², > 0).
    pub acceleration: Option<f64>,
    /// Jerk (units/s³, > 0).
    pub jerk: Option<f64>,
    /// Coarse speed (units/s, > 0).
    pub speed_switch_search: Option<f64>,
    /// Coarse distance (units, > 0).
    pub max_distance_switch_search: Option<f64>,
    /// Fine speed (units/s, > 0).
    pub speed_reference_search: Option<f64>,
    /// Fine distance (units, > 0).
    pub max_distance_reference_search: Option<f64>,
    /// ReferenceOffset (units).
    pub reference_offset: Option<f64>,
    /// NormalPosition (units).
    pub normal_position: Option<f64>,
}

impl MoveHomeCall {
    /// A call with every parameter given.
    pub fn all(p: MoveHome) -> Self {
        Self {
            direction: Some(p.direction),
            switch_config: Some(p.switch_config),
            mode: Some(p.mode),
            acceleration: Some(p.acceleration),
            jerk: Some(p.jerk),
            speed_switch_search: Some(p.speed_switch_search),
            max_distance_switch_search: Some(p.max_distance_switch_search),
            speed_reference_search: Some(p.speed_reference_search),
            max_distance_reference_search: Some(p.max_distance_reference_search),
            reference_offset: Some(p.reference_offset),
            normal_position: Some(p.normal_position),
        }
    }

    /// `last` with this call's parameters put in.
    pub fn merged(&self, last: &MoveHome) -> MoveHome {
        MoveHome {
            direction: self.direction.unwrap_or(last.direction),
            switch_config: self.switch_config.unwrap_or(last.switch_config),
            mode: self.mode.unwrap_or(last.mode),
            acceleration: self.acceleration.unwrap_or(last.acceleration),
            jerk: self.jerk.unwrap_or(last.jerk),
            speed_switch_search: self.speed_switch_search.unwrap_or(last.speed_switch_search),
            max_distance_switch_search: self
                .max_distance_switch_search
                .unwrap_or(last.max_distance_switch_search),
            speed_reference_search: self
                .speed_reference_search
                .unwrap_or(last.speed_reference_search),
            max_distance_reference_search: self
                .max_distance_reference_search
                .unwrap_or(last.max_distance_reference_search),
            reference_offset: self.reference_offset.unwrap_or(last.reference_offset),
            normal_position: self.normal_position.unwrap_or(last.normal_position),
        }
    }
}
