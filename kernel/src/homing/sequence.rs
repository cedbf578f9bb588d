//! The homing sequencer: one state machine that both Jetter's MoveHome and Beckhoff's
//! MC_StepAbsoluteSwitch are plans for (a list of searches and a way to finish).
//!
//! A search moves at its speed in a direction and watches the switches and the touch-probe
//! latches each cycle. What it looks for is a [`Goal`]: an edge of a switch cam crossed in a
//! given direction, a switch level, or an index pulse. The position of an edge or pulse is
//! always the drive's latch (issue 13 §2: exact at any speed and cycle time), never the
//! cycle-sampled position. Crossing the wanted edge in the wrong direction reverses the
//! search so it comes back over the edge the right way (seed 003: "passing the target edge
//! against the set direction reverses automatically"); reaching a limit switch reverses it
//! when the plan allows (seed 000 RefAndLimitSwitch, seed 003), else it is an error.
//!
//! Pure: no axis, no allocation. The axis feeds an [`Observation`] per cycle and carries out
//! the [`Demand`] it gets back.

use super::error::HomingError;
use super::inputs::{LimitSide, ProbeLatches, SwitchInputs};
use super::HomingStatus;

/// The input a search watches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signal {
    /// The reference (home) switch.
    Reference,
    /// A limit switch used as the reference switch (Jetter `LimitSwitch`).
    Limit(LimitSide),
}

impl Signal {
    fn level(self, i: &SwitchInputs) -> bool {
        match self {
            Signal::Reference => i.reference,
            Signal::Limit(LimitSide::Negative) => i.negative_limit,
            Signal::Limit(LimitSide::Positive) => i.positive_limit,
        }
    }

    /// What a search for it looks for, in messages.
    const fn name(self) -> &'static str {
        match self {
            Signal::Reference => "reference switch",
            Signal::Limit(LimitSide::Negative) => "negative limit switch",
            Signal::Limit(LimitSide::Positive) => "positive limit switch",
        }
    }
}

/// An edge of a switch cam: the end of the active region towards negative (`Low`) or
/// positive (`High`) positions. Moving positive, the rising edge is `Low` and the falling
/// `High`; moving negative it is the other way round.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// The cam's negative end.
    Low,
    /// The cam's positive end.
    High,
}

impl Side {
    /// The edge a `rising` (or falling) latch marks when crossed moving `m` (±1).
    pub fn of(rising: bool, m: f64) -> Self {
        if (m > 0.0) == rising {
            Side::Low
        } else {
            Side::High
        }
    }

    /// The direction from inside the cam towards this edge.
    pub const fn outward(self) -> f64 {
        match self {
            Side::Low => -1.0,
            Side::High => 1.0,
        }
    }
}

/// What a search looks for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Goal {
    /// Crossing the `side` edge of `signal`'s cam moving `approach` (`None`: either way).
    Edge {
        /// Which switch.
        signal: Signal,
        /// Which end of its cam.
        side: Side,
        /// Required direction of motion over the edge (±1).
        approach: Option<f64>,
    },
    /// `signal` at level `on` (Beckhoff mcOn / mcOff; Jetter's coarse "switch found").
    Level {
        /// Which switch.
        signal: Signal,
        /// Active (true) or inactive.
        on: bool,
    },
    /// An index (zero) pulse crossed moving `approach` (`None`: either way).
    Index {
        /// Required direction (±1).
        approach: Option<f64>,
        /// Only a pulse at or beyond what the previous search found, in the approach
        /// direction: the fine phase of a two-phase zero-pulse run re-finds the coarse
        /// pulse (not one the axis passed while braking), and a pulse after a switch edge
        /// is one beyond that edge even when both fall in one cycle.
        from_found: bool,
    },
}

impl Goal {
    fn signal(&self) -> Option<Signal> {
        match *self {
            Goal::Edge { signal, .. } | Goal::Level { signal, .. } => Some(signal),
            Goal::Index { .. } => None,
        }
    }

    fn looking_for(&self) -> &'static str {
        match *self {
            Goal::Edge { signal, .. } | Goal::Level { signal, .. } => signal.name(),
            Goal::Index { .. } => "index pulse",
        }
    }
}

/// How a search picks its first direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Start {
    /// Move in this direction (±1).
    Toward(f64),
    /// Beckhoff mcSwitchPositive / mcSwitchNegative and a one-phase switch search: on the
    /// cam, first leave it against the direction, then move in it (seed 003).
    LeaveThen(f64),
    /// The second phase after a coarse one, from a stop: on the cam, towards the goal's
    /// edge; off it, back the way the coarse phase came (it went past what it found).
    Back,
    /// Go on in the direction of the last motion (an index after an edge).
    Keep,
}

/// Which status bits a finished search sets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Marks {
    /// "Switch found" (Jetter IsSwitchFound).
    pub switch_found: bool,
    /// The search found the reference (Jetter IsReferenceFound; the last search).
    pub reference_found: bool,
}

/// One search of a plan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Search {
    /// What it looks for.
    pub goal: Goal,
    /// Its speed (units/s, > 0).
    pub speed: f64,
    /// The farthest it may travel (units, > 0; may be infinite).
    pub max_distance: f64,
    /// The parameter `max_distance` came from, for the error.
    pub distance_name: &'static str,
    /// How it starts.
    pub start: Start,
    /// The status bits it sets when done.
    pub marks: Marks,
}

/// How a run ends once the reference is found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Finish {
    /// Jetter: move to reference + `offset`, then that position becomes `normal_position`.
    MoveTo {
        /// ReferenceOffset (units, signed).
        offset: f64,
        /// NormalPosition (units).
        normal_position: f64,
    },
    /// Beckhoff: stop; the reference gets `position` (the axis stands past it).
    StopAndSet {
        /// The position the reference gets (units).
        position: f64,
    },
}

/// Up to three searches, run in order.
pub const MAX_SEARCHES: usize = 3;

/// A homing run as searches and a finish.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// The command's name, for errors.
    pub command: &'static str,
    /// The searches (the first `None` ends the list).
    pub searches: [Option<Search>; MAX_SEARCHES],
    /// Limit switches reverse a search (else reaching one is an error).
    pub reverse_at_limits: bool,
    /// How the run ends.
    pub finish: Finish,
    /// The run's direction (±1), for `Start::Keep` when nothing moved yet.
    pub direction: f64,
}

impl Plan {
    /// The limit switch whose edge a search of this plan looks for (MoveHome with
    /// `LimitSwitch` in a SwitchingEdge mode): its position comes from the touch probe,
    /// so the drive layer must route the probe to that switch while the run lasts.
    pub fn latched_limit(&self) -> Option<LimitSide> {
        self.searches.iter().flatten().find_map(|s| match s.goal {
            Goal::Edge {
                signal: Signal::Limit(side),
                ..
            } => Some(side),
            _ => None,
        })
    }
}

/// What the axis gives the sequencer each cycle (axis frame).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Observation {
    /// Actual position.
    pub actual_p: f64,
    /// Actual velocity.
    pub actual_v: f64,
    /// Set position.
    pub set_p: f64,
    /// Set velocity.
    pub set_v: f64,
    /// The last demand is carried out: set velocity reached, or target reached.
    pub settled: bool,
    /// Switch levels.
    pub inputs: SwitchInputs,
    /// Latches, in the axis frame.
    pub latches: ProbeLatches,
}

/// What the axis is to do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Demand {
    /// Go on as before.
    Keep,
    /// Run at this velocity (0: stop).
    Velocity(f64),
    /// Position to this target and stop there.
    MoveTo(f64),
    /// Done: the current set position gets this value; the axis is homed.
    SetPosition(f64),
    /// The run failed.
    Fail(HomingError),
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Stage {
    /// Braking to a stop before search `i` starts (a fine phase after a coarse one).
    Pause(usize),
    Search(usize),
    Stopping,
    Approaching,
    Done,
}

/// A running homing sequence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sequencer {
    plan: Plan,
    stage: Stage,
    /// Direction the current search moves in (±1).
    dir: f64,
    /// The search is leaving the cam first (Start::LeaveThen), then moves `then`.
    leaving: Option<f64>,
    /// Velocity last demanded.
    demanded_v: f64,
    /// Limit switches the current run reversed at.
    reversed: [bool; 2],
    travelled: f64,
    last_set_p: f64,
    /// Direction of the last motion (±1).
    last_motion: f64,
    reference: f64,
    /// What the last finished search found (axis frame).
    last_found: f64,
    status: HomingStatus,
    started: bool,
    /// The switches as the previous cycle saw them.
    prev_inputs: SwitchInputs,
}

impl Sequencer {
    /// A sequencer for `plan`; the first [`Sequencer::step`] starts it.
    pub fn new(plan: Plan) -> Self {
        Self {
            plan,
            stage: Stage::Search(0),
            dir: plan.direction,
            leaving: None,
            demanded_v: 0.0,
            reversed: [false; 2],
            travelled: 0.0,
            last_set_p: 0.0,
            last_motion: plan.direction,
            reference: 0.0,
            last_found: 0.0,
            status: HomingStatus {
                started: true,
                ..HomingStatus::default()
            },
            started: false,
            prev_inputs: SwitchInputs::default(),
        }
    }

    /// Status bits so far.
    pub fn status(&self) -> HomingStatus {
        self.status
    }

    /// The reference found (axis frame, before the position is set), once found.
    pub fn reference(&self) -> Option<f64> {
        self.status.reference_found.then_some(self.reference)
    }

    /// One cycle.
    pub fn step(&mut self, o: &Observation) -> Demand {
        let motion = motion_sign(o).unwrap_or(self.last_motion);
        if !self.started {
            self.started = true;
            self.last_set_p = o.set_p;
            self.prev_inputs = o.inputs;
            return self.begin(0, o);
        }
        self.travelled += (o.set_p - self.last_set_p).abs();
        self.last_set_p = o.set_p;
        let d = match self.stage {
            Stage::Pause(i) => {
                let hazard = self.limit_hazard(sign(o.set_v), o, self.reference_limit());
                match hazard {
                    // Braking into a limit switch the run may reverse at is part of it.
                    Some(e) if !self.plan.reverse_at_limits => Demand::Fail(e),
                    _ if o.settled => self.begin(i, o),
                    _ => Demand::Keep,
                }
            }
            Stage::Search(i) => self.search_step(i, o, motion),
            Stage::Stopping => {
                if let Some(e) = self.limit_hazard(sign(o.set_v), o, self.reference_limit()) {
                    Demand::Fail(e)
                } else if o.settled {
                    self.done(o.set_p - self.reference + self.finish_position())
                } else {
                    Demand::Keep
                }
            }
            Stage::Approaching => {
                if let Some(e) = self.limit_hazard(sign(o.set_v), o, self.reference_limit()) {
                    Demand::Fail(e)
                } else if o.settled {
                    self.done(self.finish_position())
                } else {
                    Demand::Keep
                }
            }
            Stage::Done => Demand::Keep,
        };
        if let Some(m) = motion_sign(o) {
            self.last_motion = m;
        }
        self.prev_inputs = o.inputs;
        d
    }

    fn finish_position(&self) -> f64 {
        match self.plan.finish {
            Finish::MoveTo {
                normal_position, ..
            } => normal_position,
            Finish::StopAndSet { position } => position,
        }
    }

    fn done(&mut self, position: f64) -> Demand {
        self.stage = Stage::Done;
        self.status.reference_set = true;
        Demand::SetPosition(position)
    }

    /// Starts search `i` (or the finish when there is none).
    fn begin(&mut self, i: usize, o: &Observation) -> Demand {
        let Some(s) = self.plan.searches.get(i).copied().flatten() else {
            return self.finish();
        };
        self.stage = Stage::Search(i);
        self.travelled = 0.0;
        self.leaving = None;
        let on = s.goal.signal().is_some_and(|sig| sig.level(&o.inputs));
        self.dir = match s.start {
            Start::Toward(d) => d,
            Start::LeaveThen(d) if on => {
                self.leaving = Some(d);
                -d
            }
            Start::LeaveThen(d) => d,
            Start::Back => match s.goal {
                Goal::Edge { side, .. } if on => side.outward(),
                _ => -self.last_motion,
            },
            Start::Keep => self.last_motion,
        };
        // An index pulse this very cycle, beyond what the last search found.
        if let Goal::Index { .. } = s.goal {
            if let Some(m) = motion_sign(o) {
                if self.index_hit(&s.goal, o, m) {
                    return self.found(i, s, o.latches.index.position, o);
                }
            }
        }
        // A level goal may hold already (mcOn on the cam; Jetter's coarse phase on the cam).
        if let Goal::Level { signal, on: want } = s.goal {
            if self.leaving.is_none() && signal.level(&o.inputs) == want {
                return self.found(i, s, o.actual_p, o);
            }
        }
        self.velocity(self.dir * s.speed)
    }

    /// The plan this run follows.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// The limit switch the plan uses as its reference switch, if any: braking into it
    /// after its edge is found is part of the run, not a hazard.
    fn reference_limit(&self) -> Option<Signal> {
        self.plan
            .searches
            .iter()
            .flatten()
            .filter_map(|s| s.goal.signal())
            .find(|s| matches!(s, Signal::Limit(_)))
    }

    /// Whether this cycle's index latch is the one `goal` looks for.
    fn index_hit(&self, goal: &Goal, o: &Observation, motion: f64) -> bool {
        let Goal::Index {
            approach,
            from_found,
        } = *goal
        else {
            return false;
        };
        let x = o.latches.index.position;
        let eps = 1e-9 * (1.0 + self.last_found.abs());
        o.latches.index.new
            && approach.is_none_or(|a| a == motion)
            && (!from_found || motion * (x - self.last_found) >= -eps)
    }

    fn velocity(&mut self, v: f64) -> Demand {
        if v == self.demanded_v {
            Demand::Keep
        } else {
            self.demanded_v = v;
            Demand::Velocity(v)
        }
    }

    fn finish(&mut self) -> Demand {
        match self.plan.finish {
            Finish::MoveTo { offset, .. } => {
                self.stage = Stage::Approaching;
                self.demanded_v = 0.0;
                Demand::MoveTo(self.reference + offset)
            }
            Finish::StopAndSet { .. } => {
                self.stage = Stage::Stopping;
                self.demanded_v = 0.0;
                Demand::Velocity(0.0)
            }
        }
    }

    fn found(&mut self, i: usize, s: Search, at: f64, o: &Observation) -> Demand {
        self.last_found = at;
        if s.marks.switch_found {
            self.status.switch_found = true;
        }
        if s.marks.reference_found {
            self.status.reference_found = true;
            self.reference = at;
        }
        let next = self.plan.searches.get(i + 1).copied().flatten();
        if next.is_some_and(|n| n.start == Start::Back) {
            // Jetter: the coarse phase found it; the fine phase starts from a stop, so the
            // edge or pulse is crossed at the fine speed (seed 000 §6.3.2.2).
            self.stage = Stage::Pause(i + 1);
            return self.velocity(0.0);
        }
        self.begin(i + 1, o)
    }

    /// A limit switch the search runs into: a reversal, or an error.
    fn limit_hazard(
        &self,
        towards: f64,
        o: &Observation,
        goal: Option<Signal>,
    ) -> Option<HomingError> {
        if towards == 0.0 || !o.inputs.limit_towards(towards) {
            return None;
        }
        let side = LimitSide::towards(towards);
        if goal == Some(Signal::Limit(side)) {
            return None;
        }
        Some(HomingError::LimitSwitch {
            command: self.plan.command,
            side,
        })
    }

    fn search_step(&mut self, i: usize, o: &Observation, motion: f64) -> Demand {
        let Some(s) = self.plan.searches.get(i).copied().flatten() else {
            return self.finish();
        };
        // Edges and pulses crossed this cycle, in the order they were crossed.
        let l = o.latches;
        let mut events = [(false, 0.0, false); 2]; // (new, position, rising)
        if s.goal.signal().is_some() {
            events = [
                (l.rising.new, l.rising.position, true),
                (l.falling.new, l.falling.position, false),
            ];
            if motion * (events[1].1 - events[0].1) < 0.0 {
                events.swap(0, 1);
            }
        }
        match s.goal {
            Goal::Edge {
                signal,
                side,
                approach,
            } => {
                for (new, x, rising) in events {
                    if !new || Side::of(rising, motion) != side {
                        continue;
                    }
                    let level = signal.level(&o.inputs);
                    if matches!(signal, Signal::Limit(_))
                        && (level != rising || signal.level(&self.prev_inputs) == rising)
                    {
                        // A limit switch's cam reaches to the end of the travel: crossing its
                        // edge changes its level in the same cycle the drive latches it, and
                        // the level stays. A latch without that change is another input's (a
                        // probe still on the home switch: the drive's probe source, 0x60D0,
                        // is not the limit switch), never the limit's edge.
                        continue;
                    }
                    match approach {
                        Some(a) if a != motion => {
                            // Over the wanted edge the wrong way: come back over it.
                            self.leaving = None;
                            self.dir = a;
                        }
                        _ => return self.found(i, s, x, o),
                    }
                }
            }
            Goal::Level { signal, on } => {
                if self.leaving.is_none() && signal.level(&o.inputs) == on {
                    let latch = if on { l.rising } else { l.falling };
                    let x = if latch.new {
                        latch.position
                    } else {
                        o.actual_p
                    };
                    return self.found(i, s, x, o);
                }
            }
            Goal::Index { .. } => {
                if self.index_hit(&s.goal, o, motion) {
                    return self.found(i, s, l.index.position, o);
                }
            }
        }
        // Off the cam it was leaving: now the run's own direction.
        if let (Some(then), Some(sig)) = (self.leaving, s.goal.signal()) {
            if !sig.level(&o.inputs) {
                self.leaving = None;
                self.dir = then;
                if let Goal::Level { on: false, .. } = s.goal {
                    let x = if l.falling.new {
                        l.falling.position
                    } else {
                        o.actual_p
                    };
                    return self.found(i, s, x, o);
                }
            }
        }
        if self.travelled > s.max_distance {
            return Demand::Fail(HomingError::DistanceExceeded {
                command: self.plan.command,
                distance: s.distance_name,
                limit: s.max_distance,
                travelled: self.travelled,
                looking_for: s.goal.looking_for(),
            });
        }
        if let Some(e) = self.limit_hazard(self.dir, o, s.goal.signal()) {
            // Only a switch search turns round at a limit switch (seed 000 RefAndLimitSwitch:
            // "reverses and searches the reference switch"); an index pulse that is not there
            // before the limit switch is not there.
            if !self.plan.reverse_at_limits || matches!(s.goal, Goal::Index { .. }) {
                return Demand::Fail(e);
            }
            let k = usize::from(self.dir > 0.0);
            if self.reversed.get(k).copied().unwrap_or(true) {
                return Demand::Fail(HomingError::NotFoundBetweenLimits {
                    command: self.plan.command,
                    looking_for: s.goal.looking_for(),
                });
            }
            if let Some(r) = self.reversed.get_mut(k) {
                *r = true;
            }
            self.dir = -self.dir;
            if let Some(then) = self.leaving {
                // Leaving the cam into a limit: the cam fills the travel; turn round.
                self.leaving = None;
                self.dir = then;
            }
        }
        self.velocity(self.dir * s.speed)
    }
}

fn sign(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// The direction the load moves in: the actual velocity, or the set velocity while the
/// actual is (near) zero.
fn motion_sign(o: &Observation) -> Option<f64> {
    let tiny = 1e-9;
    if o.actual_v.abs() > tiny {
        Some(sign(o.actual_v))
    } else if o.set_v.abs() > tiny {
        Some(sign(o.set_v))
    } else {
        None
    }
}
