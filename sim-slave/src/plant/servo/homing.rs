//! The drive's homing mode (CiA 402-2 §10.4, IEC 61800-7-201 "Homing mode"; mode of
//! operation 6): the drive searches its own limit switches, home switch and encoder index
//! pulse (the cams of [`super::probe::DriveSwitches`], the index of
//! [`super::probe::index_crossing`]) as the homing method says, and sets its position at
//! the home position it found.
//!
//! Objects: 0x6098 homing method, 0x6099:01 speed during search for switch, 0x6099:02
//! speed during search for zero, 0x609A homing acceleration, 0x607C home offset.
//! Controlword bit 4 (homing operation start): its rising edge starts homing, its falling
//! edge while homing interrupts it; bit 8 (halt) stops the motion with the homing
//! acceleration (CiA 402-2 §10.4.1). Statusword bit 10 target reached, 12 homing attained,
//! 13 homing error (§10.4.2):
//!
//! | 13 | 12 | 10 | |
//! |---|---|---|---|
//! | 0 | 0 | 0 | homing in progress |
//! | 0 | 0 | 1 | interrupted, or not started |
//! | 0 | 1 | 1 | homing attained, the drive stands at the home position |
//! | 1 | 0 | 0/1 | homing error, the velocity not yet 0 / 0 |
//!
//! Methods (§10.4.3, the method diagrams): 1–2 a limit switch and the index pulse beyond
//! it; 3–6 a home switch taken as a level (its edge on the positive side for 3–4, the
//! negative for 5–6) and the index pulse to either side; 7–14 a home switch with two edges
//! between the limit switches, initial move positive (7–10, reversing at the positive
//! limit switch) or negative (11–14, at the negative one), the index pulse on either side
//! of either edge; 17–30 as 1–14 with the switch edge itself the home position; 33–34 the
//! next index pulse negative / positive; 35 and 37 the current position; 0 no homing
//! (nothing moves, homing attained). 15, 16, 31, 32, 36 are reserved and negative values
//! manufacturer-specific: this drive has none of them, a write of one is refused with
//! SDO abort 0x06090030 (CiA 301 value range).
//!
//! Rules a real drive keeps that the simulator keeps too: an edge counts only in the
//! direction the method moves (the load overshoots the switch while it reverses); the
//! first leg searches at the switch speed, every later one at the zero speed; a limit
//! switch the method does not use, or reaches in the wrong direction, or — methods 7–14
//! and 23–30 — its reversal switch reached a second time (the home switch is not between
//! the limits) is a homing error: the drive stops with the homing acceleration and sets
//! bit 13. Found, the drive stops and positions back onto the home position, exact to the
//! count (the edge or index is taken where it happened, as a touch probe latches it), and
//! sets its position there to minus the home offset: "the zero position is offset from the
//! home position by adding the home offset to the home position" (CiA 402-2, 0x607C). Then
//! homing attained and target reached.

use super::probe::{index_crossing, DriveSwitches, HOME_INPUT};

/// 0x60FD bit of the negative limit switch.
pub const NEGATIVE_LIMIT_INPUT: u8 = 0;
/// 0x60FD bit of the positive limit switch.
pub const POSITIVE_LIMIT_INPUT: u8 = 1;

/// Whether CiA 402-2 defines `method` and this drive has it: 0–14, 17–30, 33–35, 37.
pub const fn defined(method: i8) -> bool {
    matches!(method, 0..=14 | 17..=30 | 33..=35 | 37)
}

/// A set of homing methods (−128…127).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MethodSet([u64; 4]);

impl MethodSet {
    /// No method.
    pub const EMPTY: Self = Self([0; 4]);

    /// Adds `m`.
    pub fn insert(&mut self, m: i8) {
        let i = (m as u8) as usize;
        if let Some(w) = self.0.get_mut(i / 64) {
            *w |= 1 << (i % 64);
        }
    }

    /// The set as bits (value `v` at bit `v as u8`).
    pub const fn bits(&self) -> [u64; 4] {
        self.0
    }

    /// Whether `m` is in the set.
    pub fn contains(&self, m: i8) -> bool {
        let i = (m as u8) as usize;
        self.0.get(i / 64).is_some_and(|w| w & (1 << (i % 64)) != 0)
    }
}

/// Faults of real drives' homing that the field reports, to inject (`[slave.homing]`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HomingFaults {
    /// The drive homes but never sets homing attained (its statusword stays "in
    /// progress"): a firmware that hangs at the end.
    pub never_attains: bool,
    /// Methods the drive refuses although CiA 402 defines them (e.g. 0).
    pub refused: MethodSet,
}

impl HomingFaults {
    /// Whether a write of `method` to 0x6098 is taken.
    pub fn accepts(&self, method: i8) -> bool {
        defined(method) && !self.refused.contains(method)
    }
}

/// The homing objects (SDO-written settings).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HomingSettings {
    /// 0x6098 homing method.
    pub method: i8,
    /// 0x6099:01 speed during search for switch (counts/s).
    pub speed_switch: u32,
    /// 0x6099:02 speed during search for zero (counts/s).
    pub speed_zero: u32,
    /// 0x609A homing acceleration (counts/s²).
    pub acceleration: u32,
    /// 0x607C home offset (counts).
    pub home_offset: i32,
}

impl Default for HomingSettings {
    fn default() -> Self {
        Self {
            method: 0,
            // 1 and 0.1 rev/s, 10 rev/s² for a 2¹⁷ encoder.
            speed_switch: 131_072,
            speed_zero: 13_107,
            acceleration: 1_310_720,
            home_offset: 0,
        }
    }
}

/// What ends a leg of a search.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Until {
    /// Input `n` becomes active.
    On(u8),
    /// Input `n` becomes inactive.
    Off(u8),
    /// The index pulse passes.
    Index,
}

/// One leg: move in direction `dir` (±1) until the event.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Leg {
    dir: i8,
    until: Until,
}

/// Most legs a method has.
const MAX_LEGS: usize = 5;

/// The legs of a search.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Plan {
    legs: [Leg; MAX_LEGS],
    len: usize,
}

impl Plan {
    fn of(legs: &[Leg]) -> Self {
        let mut p = Plan {
            legs: [Leg {
                dir: 1,
                until: Until::Index,
            }; MAX_LEGS],
            len: 0,
        };
        for l in legs.iter().take(MAX_LEGS) {
            if let Some(slot) = p.legs.get_mut(p.len) {
                *slot = *l;
                p.len += 1;
            }
        }
        p
    }

    /// Without the final index leg (methods 17–30: the edge is the home position).
    fn without_index(mut self) -> Self {
        if self.len > 1 && self.legs.get(self.len - 1).map(|l| l.until) == Some(Until::Index) {
            self.len -= 1;
        }
        self
    }
}

/// How a method treats the limit switches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Limits {
    /// None used: any reached in the direction of travel is an error.
    Unused,
    /// This one is the method's switch (1, 2, 17, 18); the other is an error.
    Searched(u8),
    /// Reverse once at this one (7–14, 23–30), going on with the plan; reaching it again,
    /// or the other, is an error.
    Reverse(u8, Plan),
}

/// Where the drive's homing is.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    /// Not homing: holding. `attained`: the last homing ended at its home position;
    /// `error`: it ended in a homing error.
    Idle { attained: bool, error: bool },
    /// Searching: leg `n` of `plan`.
    Search {
        plan: Plan,
        n: usize,
        limits: Limits,
        reversed: bool,
    },
    /// Found at `home` (counts): positioning onto it.
    Return { home: i64 },
    /// Braking to a stop (error, halt, interrupt), then `Idle { attained: false, error }`.
    Stop { error: bool },
}

/// The homing mode's motion and status.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Homing {
    phase: Phase,
    settings: HomingSettings,
    /// Position demand (counts, the drive's raw position) and its velocity (counts/s).
    demand: f64,
    velocity: f64,
    /// The home position found and the shift to apply there, taken by the drive once it
    /// stands on it: `Some((home, offset))`.
    pending_set: Option<(i64, i32)>,
    faults: HomingFaults,
}

/// What the drive does with its position after a homing (counts to add to the raw
/// position so that the home position reads as minus the home offset).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PositionSet {
    /// The home position (raw counts).
    pub home: i64,
    /// The value the position actual value has there.
    pub value: i64,
}

impl Homing {
    /// Not homing, holding at `at` (counts).
    pub fn idle(at: f64, faults: HomingFaults) -> Self {
        Self {
            phase: Phase::Idle {
                attained: false,
                error: false,
            },
            settings: HomingSettings::default(),
            demand: at,
            velocity: 0.0,
            pending_set: None,
            faults,
        }
    }

    /// The homing objects.
    pub fn settings(&self) -> &HomingSettings {
        &self.settings
    }

    /// The homing objects, to change (SDO).
    pub fn settings_mut(&mut self) -> &mut HomingSettings {
        &mut self.settings
    }

    /// The position demand (counts).
    pub fn demand(&self) -> f64 {
        self.demand
    }

    /// Whether a search or a positioning is running (bit 4 high, not halted, no error).
    pub fn running(&self) -> bool {
        matches!(self.phase, Phase::Search { .. } | Phase::Return { .. })
    }

    /// Holds at `at` (the mode was entered, or the drive enabled): not started; what an
    /// earlier homing attained stays attained.
    pub fn hold(&mut self, at: f64) {
        self.demand = at;
        self.velocity = 0.0;
        if !matches!(self.phase, Phase::Idle { .. }) {
            self.phase = Phase::Idle {
                attained: false,
                error: false,
            };
        }
    }

    /// Bit 4's rising edge: starts the method at the drive's raw position `at` (counts,
    /// the load standing or moving at `velocity`).
    pub fn start(&mut self, at: f64, velocity: f64, switches: &DriveSwitches) {
        self.demand = at;
        self.velocity = velocity;
        self.pending_set = None;
        let m = self.settings.method;
        let here = at.round() as i64;
        let level = |input: u8| switches.digital_inputs(here) & (1 << input) != 0;
        self.phase = match m {
            0 => Phase::Idle {
                attained: true,
                error: false,
            },
            35 | 37 => {
                self.pending_set = Some((here, self.settings.home_offset));
                Phase::Return { home: here }
            }
            _ => match plan(m, here, level, switches) {
                Some((plan, limits)) => Phase::Search {
                    plan,
                    n: 0,
                    limits,
                    reversed: false,
                },
                None => Phase::Stop { error: true },
            },
        };
    }

    /// Bit 4's falling edge while homing, or the halt bit: stop with the homing
    /// acceleration; homing is not attained (interrupted).
    pub fn interrupt(&mut self) {
        if self.running() {
            self.pending_set = None;
            self.phase = Phase::Stop { error: false };
        }
    }

    /// Statusword bits 10, 12, 13 (see the module doc); `standing`: the load stands;
    /// `halted`: the controlword's halt bit is set (bit 10 then says the axle has
    /// velocity 0, CiA 402-2 §10.4.2, whatever the homing's state).
    pub fn status_bits(&self, standing: bool, halted: bool) -> u16 {
        const TARGET_REACHED: u16 = 1 << 10;
        const ATTAINED: u16 = 1 << 12;
        const ERROR: u16 = 1 << 13;
        let halt = if halted && standing {
            TARGET_REACHED
        } else {
            0
        };
        halt | match self.phase {
            Phase::Idle { attained: true, .. } if self.faults.never_attains => 0,
            Phase::Idle { attained: true, .. } => ATTAINED | TARGET_REACHED,
            Phase::Idle { error: true, .. } => ERROR | if standing { TARGET_REACHED } else { 0 },
            Phase::Idle { .. } => TARGET_REACHED,
            Phase::Search { .. } | Phase::Return { .. } => 0,
            Phase::Stop { error: true } => ERROR,
            Phase::Stop { error: false } => 0,
        }
    }

    /// One loop period of `h` s: the velocity the position loop is to follow
    /// (`kp`: its gain, `position`: the load's raw position), limited to `vmax`.
    pub fn command(&mut self, h: f64, kp: f64, position: f64, vmax: f64) -> f64 {
        let a = f64::from(self.settings.acceleration.max(1));
        let fast = f64::from(self.settings.speed_switch).min(vmax);
        let slow = f64::from(self.settings.speed_zero).min(vmax);
        let now = self.demand;
        let target_v = match self.phase {
            Phase::Search { plan, n, .. } => {
                let leg = plan.legs.get(n).copied().unwrap_or(Leg {
                    dir: 1,
                    until: Until::Index,
                });
                let speed = if n == 0 && leg.until != Until::Index {
                    fast
                } else {
                    slow
                };
                f64::from(leg.dir) * speed
            }
            Phase::Return { home } => {
                // Towards the home position, braking in time to stand on it.
                let d = home as f64 - self.demand;
                if d.abs() <= a * h * h && self.velocity.abs() <= 2.0 * a * h {
                    self.demand = home as f64;
                    self.velocity = 0.0;
                    return (kp * (now - position)).clamp(-vmax, vmax);
                }
                d.signum() * slow.min((2.0 * a * d.abs()).sqrt())
            }
            Phase::Idle { .. } | Phase::Stop { .. } => 0.0,
        };
        let dv = a * h;
        self.velocity = if (target_v - self.velocity).abs() <= dv {
            target_v
        } else {
            self.velocity + dv * (target_v - self.velocity).signum()
        };
        self.demand += self.velocity * h;
        if let Phase::Stop { error } = self.phase {
            if self.velocity == 0.0 {
                self.phase = Phase::Idle {
                    attained: false,
                    error,
                };
            }
        }
        (kp * (now - position) + self.velocity).clamp(-vmax, vmax)
    }

    /// The load moved from count `from` to count `to` (one loop period): the search's
    /// events. `standing`: the load stands (for the end of the positioning).
    pub fn observe(
        &mut self,
        from: i64,
        to: i64,
        switches: &DriveSwitches,
        index_at: i64,
        counts_per_rev: i64,
    ) {
        let Phase::Search {
            plan,
            n,
            limits,
            reversed,
        } = self.phase
        else {
            return;
        };
        let Some(leg) = plan.legs.get(n).copied() else {
            return;
        };
        let travel = (to - from).signum() as i8;
        let level = |input: u8, at: i64| switches.digital_inputs(at) & (1 << input) != 0;
        // The leg's event, in its direction only.
        if travel == leg.dir {
            let event = match leg.until {
                Until::On(i) if !level(i, from) && level(i, to) => edge(switches, i, from, to),
                Until::Off(i) if level(i, from) && !level(i, to) => edge(switches, i, from, to),
                Until::Index => index_crossing(from, to, index_at, counts_per_rev).map(|e| e.at),
                _ => None,
            };
            if let Some(at) = event {
                if n + 1 >= plan.len {
                    self.pending_set = Some((at, self.settings.home_offset));
                    self.phase = Phase::Return { home: at };
                } else {
                    self.phase = Phase::Search {
                        plan,
                        n: n + 1,
                        limits,
                        reversed,
                    };
                }
                return;
            }
        }
        // A limit switch active ahead of the leg (CiA 402-2 §10.4.3: the methods that
        // do not search a limit switch, or reverse at it only once, end in an error).
        let ahead = if leg.dir < 0 {
            NEGATIVE_LIMIT_INPUT
        } else {
            POSITIVE_LIMIT_INPUT
        };
        if !level(ahead, to) {
            return;
        }
        match limits {
            Limits::Searched(i) if i == ahead => {}
            Limits::Reverse(i, after) if i == ahead && !reversed => {
                self.phase = Phase::Search {
                    plan: after,
                    n: 0,
                    limits,
                    reversed: true,
                };
            }
            _ => {
                self.pending_set = None;
                self.phase = Phase::Stop { error: true };
            }
        }
    }

    /// Once the load stands on the home position found (within a count): the position
    /// to set there, once; the homing is then attained.
    pub fn take_position_set(&mut self, position: f64, standing: bool) -> Option<PositionSet> {
        let Phase::Return { home } = self.phase else {
            return None;
        };
        if self.demand != home as f64 || !standing || (position - home as f64).abs() > 1.0 {
            return None;
        }
        self.phase = Phase::Idle {
            attained: true,
            error: false,
        };
        self.pending_set.take().map(|(home, offset)| PositionSet {
            home,
            value: -i64::from(offset),
        })
    }
}

/// The count at which input `input`'s cam changes state between `from` and `to`: the
/// first count of the new state in the direction of travel.
fn edge(switches: &DriveSwitches, input: u8, from: i64, to: i64) -> Option<i64> {
    let cam = switches.cam(input)?;
    let (lo, hi) = (from.min(to), from.max(to));
    let candidates = if to > from {
        [cam.from, cam.to + 1]
    } else {
        [cam.to, cam.from - 1]
    };
    candidates
        .into_iter()
        .filter(|c| *c > lo - 1 && *c <= hi && *c != from)
        .filter(|c| (c - from).signum() == (to - from).signum())
        .min_by_key(|c| (c - from).abs())
}

/// The legs of `method` from where the drive stands (`level`: an input's state there),
/// and how it treats the limit switches; `None` for a method it does not have.
fn plan(
    method: i8,
    here: i64,
    level: impl Fn(u8) -> bool,
    switches: &DriveSwitches,
) -> Option<(Plan, Limits)> {
    let leg = |dir: i8, until: Until| Leg { dir, until };
    let h = HOME_INPUT;
    match method {
        // 1, 2, 17, 18: a limit switch, then (1, 2) the index pulse beyond it.
        1 | 2 | 17 | 18 => {
            let (s, lim) = if method % 2 == 1 {
                (-1, NEGATIVE_LIMIT_INPUT)
            } else {
                (1, POSITIVE_LIMIT_INPUT)
            };
            let p = if level(lim) {
                Plan::of(&[leg(-s, Until::Off(lim)), leg(-s, Until::Index)])
            } else {
                Plan::of(&[
                    leg(s, Until::On(lim)),
                    leg(-s, Until::Off(lim)),
                    leg(-s, Until::Index),
                ])
            };
            let p = if method >= 17 { p.without_index() } else { p };
            Some((p, Limits::Searched(lim)))
        }
        // 3–6, 19–22: the home switch as a level; 3, 4 positive, 5, 6 negative; the index
        // (3, 4, 5, 6) behind or ahead of the edge.
        3..=6 | 19..=22 => {
            let m = if method >= 19 { method - 16 } else { method };
            let s: i8 = if m <= 4 { 1 } else { -1 };
            let behind = m == 3 || m == 5;
            let p = match (level(h), behind) {
                (false, true) => Plan::of(&[
                    leg(s, Until::On(h)),
                    leg(-s, Until::Off(h)),
                    leg(-s, Until::Index),
                ]),
                (true, true) => Plan::of(&[leg(-s, Until::Off(h)), leg(-s, Until::Index)]),
                (false, false) => Plan::of(&[leg(s, Until::On(h)), leg(s, Until::Index)]),
                (true, false) => Plan::of(&[
                    leg(-s, Until::Off(h)),
                    leg(s, Until::On(h)),
                    leg(s, Until::Index),
                ]),
            };
            let p = if method >= 19 { p.without_index() } else { p };
            Some((p, Limits::Unused))
        }
        // 7–14, 23–30: a home cam between the limit switches; 7–10 (23–26) move positive
        // first and reverse at the positive limit switch, 11–14 (27–30) the mirror.
        7..=14 | 23..=30 => {
            let m = if method >= 23 { method - 16 } else { method };
            let (s, v, lim) = if m <= 10 {
                (1i8, m - 7, POSITIVE_LIMIT_INPUT)
            } else {
                (-1i8, m - 11, NEGATIVE_LIMIT_INPUT)
            };
            let (f, b) = (s, -s);
            let i = Until::Index;
            let (on, off) = (Until::On(h), Until::Off(h));
            // In the method's frame: the cam's near ("B") and far ("F") edge.
            let (behind_plan, on_plan, after) = match v {
                // Index behind B.
                0 => (
                    Plan::of(&[leg(f, on), leg(b, off), leg(b, i)]),
                    Plan::of(&[leg(b, off), leg(b, i)]),
                    Plan::of(&[leg(b, on), leg(b, off), leg(b, i)]),
                ),
                // Index ahead of B.
                1 => (
                    Plan::of(&[leg(f, on), leg(f, i)]),
                    Plan::of(&[leg(b, off), leg(f, on), leg(f, i)]),
                    Plan::of(&[leg(b, on), leg(b, off), leg(f, on), leg(f, i)]),
                ),
                // Index behind F.
                2 => (
                    Plan::of(&[leg(f, on), leg(f, off), leg(b, on), leg(b, i)]),
                    Plan::of(&[leg(f, off), leg(b, on), leg(b, i)]),
                    Plan::of(&[leg(b, on), leg(b, i)]),
                ),
                // Index ahead of F.
                _ => (
                    Plan::of(&[leg(f, on), leg(f, off), leg(f, i)]),
                    Plan::of(&[leg(f, off), leg(f, i)]),
                    Plan::of(&[leg(b, on), leg(f, off), leg(f, i)]),
                ),
            };
            let strip = |p: Plan| if method >= 23 { p.without_index() } else { p };
            // Off the cam past it (in the method's direction) searches on into the
            // limit switch and reverses there, as from behind it.
            let p = if level(h) { on_plan } else { behind_plan };
            let _ = (here, switches);
            Some((strip(p), Limits::Reverse(lim, strip(after))))
        }
        33 => Some((Plan::of(&[leg(-1, Until::Index)]), Limits::Unused)),
        34 => Some((Plan::of(&[leg(1, Until::Index)]), Limits::Unused)),
        _ => None,
    }
}
