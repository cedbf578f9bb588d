//! Beckhoff MC_StepAbsoluteSwitch (Tc3_MC2_AdvancedHoming; seed 003): search the reference
//! cam with automatic reversal at the limit switches; `Direction` says how the run starts,
//! `SwitchMode` which crossing ends it. The reference gets `position` at that crossing
//! (latched); the axis stops past it and keeps standing there.
//!
//! Start positions (seed 003): ① between the negative limit and the cam, ② on the cam,
//! ③ between the cam and the positive limit. Every Direction × SwitchMode works from each.
//!
//! **Where TwinCAT is wrong (seed 003, library 3.0.23.0) and what we do:**
//! - `EdgeSwitchPositive` from ② with `SwitchNegative`: the mode ends on the cam's negative
//!   edge; the direction says "on the cam, first leave it positive, then search negative".
//!   TwinCAT was measured taking another path and ending elsewhere. We leave positive over
//!   the positive edge (not the wanted one), turn and search negative over the cam, and end
//!   on the negative edge moving negative — the path the seed draws as expected.
//! - `EdgeSwitchNegative` from ② with `SwitchPositive`/`SwitchNegative`: the seed expects the
//!   run to end moving positive on the positive edge; TwinCAT reverses once more and ends
//!   moving negative. We end moving positive: with `SwitchNegative` at the leaving crossing
//!   itself, with `SwitchPositive` after leaving negative and crossing the cam positive.
//! - Small decelerations: TwinCAT may never finish when the axis brakes past the edge. The
//!   edge here is the latch, and crossings during braking and reversal are taken for what
//!   they are, so the run ends however far the axis brakes.
//!
//! `On` and `Off` are level modes as the seed defines them: started where the level already
//! holds (`On` on the cam with `Positive`/`Negative`, `Off` off it), the run ends at once at
//! the actual position — the seed warns that this cannot locate the reference; use a
//! `Switch…` direction (which leaves the cam first) or an edge mode for a reference.

use super::sequence::{Finish, Goal, Marks, Plan, Search, Side, Signal, Start};

/// How the run starts (Beckhoff MC_HOME_DIRECTION).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HomeDirection {
    /// Start positive; reverse at a limit or where the mode requires.
    Positive,
    /// Start negative.
    Negative,
    /// Off the cam start positive; on the cam first leave it negative, then positive.
    SwitchPositive,
    /// Off the cam start negative; on the cam first leave it positive, then negative.
    SwitchNegative,
}

impl HomeDirection {
    /// The set direction (±1).
    pub const fn sign(self) -> f64 {
        match self {
            Self::Positive | Self::SwitchPositive => 1.0,
            Self::Negative | Self::SwitchNegative => -1.0,
        }
    }

    /// Every direction.
    pub const ALL: [Self; 4] = [
        Self::Positive,
        Self::Negative,
        Self::SwitchPositive,
        Self::SwitchNegative,
    ];
}

/// Which crossing ends the run (Beckhoff MC_SWITCH_MODE, seed 003).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SwitchMode {
    /// When the cam signal is on.
    On,
    /// When the cam signal is off.
    Off,
    /// Rising edge crossed moving in the set direction.
    RisingEdge,
    /// Falling edge crossed moving in the set direction.
    FallingEdge,
    /// Rising edge crossed moving against the set direction.
    RisingEdgeInverse,
    /// Falling edge crossed moving against the set direction.
    FallingEdgeInverse,
    /// The cam's negative edge (rising moving positive, falling moving negative).
    EdgeSwitchPositive,
    /// The cam's positive edge (falling moving positive, rising moving negative).
    EdgeSwitchNegative,
}

impl SwitchMode {
    /// Every mode.
    pub const ALL: [Self; 8] = [
        Self::On,
        Self::Off,
        Self::RisingEdge,
        Self::FallingEdge,
        Self::RisingEdgeInverse,
        Self::FallingEdgeInverse,
        Self::EdgeSwitchPositive,
        Self::EdgeSwitchNegative,
    ];

    /// The goal of the search for set direction `d` (±1).
    pub fn goal(self, d: f64) -> Goal {
        let signal = Signal::Reference;
        let edge = |rising: bool, a: f64| Goal::Edge {
            signal,
            side: Side::of(rising, a),
            approach: Some(a),
        };
        match self {
            Self::On => Goal::Level { signal, on: true },
            Self::Off => Goal::Level { signal, on: false },
            Self::RisingEdge => edge(true, d),
            Self::FallingEdge => edge(false, d),
            Self::RisingEdgeInverse => edge(true, -d),
            Self::FallingEdgeInverse => edge(false, -d),
            Self::EdgeSwitchPositive => Goal::Edge {
                signal,
                side: Side::Low,
                approach: None,
            },
            Self::EdgeSwitchNegative => Goal::Edge {
                signal,
                side: Side::High,
                approach: None,
            },
        }
    }
}

/// MC_StepAbsoluteSwitch's inputs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepAbsoluteSwitch {
    /// How the run starts.
    pub direction: HomeDirection,
    /// Which crossing ends it.
    pub switch_mode: SwitchMode,
    /// Position the reference gets (units).
    pub position: f64,
    /// Search speed (units/s, > 0).
    pub velocity: f64,
    /// Acceleration (units/s², > 0).
    pub acceleration: f64,
    /// Deceleration (units/s², > 0): also how hard the search reverses.
    pub deceleration: f64,
    /// Jerk (units/s³, > 0).
    pub jerk: f64,
    /// Farthest the search may travel (units, > 0; infinite: only the limit switches
    /// bound it).
    pub distance_limit: f64,
}

impl StepAbsoluteSwitch {
    /// The run as one search and a stop.
    pub fn plan(&self) -> Plan {
        let d = self.direction.sign();
        let start = match self.direction {
            HomeDirection::Positive | HomeDirection::Negative => Start::Toward(d),
            HomeDirection::SwitchPositive | HomeDirection::SwitchNegative => Start::LeaveThen(d),
        };
        Plan {
            command: "StepAbsoluteSwitch",
            searches: [
                Some(Search {
                    goal: self.switch_mode.goal(d),
                    speed: self.velocity,
                    max_distance: self.distance_limit,
                    distance_name: "DistanceLimit",
                    start,
                    marks: Marks {
                        switch_found: true,
                        reference_found: true,
                    },
                }),
                None,
                None,
            ],
            reverse_at_limits: true,
            finish: Finish::StopAndSet {
                position: self.position,
            },
            direction: d,
        }
    }
}
