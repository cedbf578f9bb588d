//! The set-value source of an axis: what produces its set values each cycle.
//!
//! A source is a value the axis holds ([`Motion`] with its [`MotionKind`]); a new kind of
//! source (homing, gearing, a group path) is a new variant, not a new path through `step`.

use super::command::{BufferMode, MoveDirection, MovePtp, MoveVelocity};
use super::handle::HandleId;
use crate::profile::{KinematicState, Limits, Profile, RampType};

/// When a profile started: the time of cycle `tick` plus `offset_s` (0 ≤ offset < dt).
/// Kept as ticks so long moves never accumulate floating-point time error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Epoch {
    /// Cycle index.
    pub tick: u64,
    /// Seconds after that cycle's time.
    pub offset_s: f64,
}

impl Epoch {
    /// An epoch exactly at a cycle.
    pub const fn at(tick: u64) -> Self {
        Self {
            tick,
            offset_s: 0.0,
        }
    }

    /// Seconds from this epoch to cycle `now`.
    pub fn elapsed(&self, now: u64, dt: f64) -> f64 {
        let ticks = now as i128 - self.tick as i128;
        ticks as f64 * dt - self.offset_s
    }

    /// This epoch moved `secs` later, normalised so that `offset_s < dt`.
    pub fn later(&self, secs: f64, dt: f64) -> Self {
        let total = self.offset_s + secs.max(0.0);
        let whole = (total / dt).floor();
        let offset = total - whole * dt;
        // Guard the rounding edge where `offset` comes out as `dt`.
        if offset >= dt {
            Self {
                tick: self.tick + whole as u64 + 1,
                offset_s: 0.0,
            }
        } else {
            Self {
                tick: self.tick + whole as u64,
                offset_s: offset.max(0.0),
            }
        }
    }
}

/// Dynamic parameters of one move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MoveParams {
    /// Speed, acceleration, deceleration and jerk of the move.
    pub limits: Limits,
    /// Ramp type.
    pub ramp: RampType,
}

/// What a running motion is doing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MotionKind {
    /// Point-to-point to `target` (in the axis' position frame).
    Ptp {
        /// Target in the axis frame.
        target: f64,
        /// Target window (units).
        window: f64,
        /// Target position monitoring once the set value stands at the target.
        settle: Settle,
    },
    /// Constant velocity (MoveVelocity).
    Velocity {
        /// Direction.
        direction: MoveDirection,
    },
    /// Jog (Logix MAJ) as the axis' own motion.
    Jog,
    /// Halt: decelerate (and for AtActualPosition come back) — ends at `target`.
    Halt {
        /// Where it ends, in the axis frame.
        target: f64,
    },
    /// MC_Stop: decelerate and lock.
    Stop,
    /// QuickStop: decelerate with the quick-stop deceleration, then disable.
    QuickStop,
    /// Power.Disable while moving: decelerate, then disable.
    Disable,
    /// A homing run (MoveHome, StepAbsoluteSwitch): the homing sequencer replans the
    /// profile as it goes and ends the motion itself.
    Home,
}

impl MotionKind {
    /// Whether the motion ends by itself (its profile has an end and the command is then
    /// done). Velocity moves and jogs go on at their speed.
    /// Homing runs are not: the sequencer ends them.
    pub const fn is_finite(&self) -> bool {
        !matches!(
            self,
            MotionKind::Velocity { .. } | MotionKind::Jog | MotionKind::Home
        )
    }

    /// Whether the axis is in ContinuousMotion while this runs.
    pub const fn is_continuous(&self) -> bool {
        matches!(self, MotionKind::Velocity { .. } | MotionKind::Jog)
    }
}

/// Target position monitoring of a PTP move whose set value has reached its target (the
/// move is then settling: Done once the actual has stayed in the window for the dwell).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Settle {
    /// The first cycle the set value stood at the target (`None`: still on its way).
    pub since: Option<u64>,
    /// The first cycle of the current unbroken run of cycles with the actual position in
    /// the target window (`None`: outside it).
    pub in_window_since: Option<u64>,
}

/// A running motion: a planned profile, when it started, and the command it serves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// What it does.
    pub kind: MotionKind,
    /// The planned set values.
    pub profile: Profile,
    /// When `profile` starts.
    pub epoch: Epoch,
    /// Parameters it was planned with (kept for on-the-fly changes).
    pub params: MoveParams,
    /// The command's handle.
    pub handle: HandleId,
    /// The command's name, for errors.
    pub command: &'static str,
    /// Decel jerk for jogs with separate accel/decel jerk (otherwise = params jerk).
    pub decel_jerk: f64,
}

impl Motion {
    /// Set values at cycle `now`.
    pub fn sample(&self, now: u64, dt: f64) -> KinematicState {
        self.profile.sample(self.epoch.elapsed(now, dt))
    }

    /// Whether the profile has ended by cycle `now`.
    pub fn ended(&self, now: u64, dt: f64) -> bool {
        self.epoch.elapsed(now, dt) >= self.profile.duration()
    }

    /// Time at which the profile ends.
    pub fn end_epoch(&self, dt: f64) -> Epoch {
        self.epoch.later(self.profile.duration(), dt)
    }
}

/// A move waiting behind the running one (buffered or blending).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Queued {
    /// A PTP move; its target is resolved when it starts (RelTarget against the previous
    /// target, modulo modes against the position it starts from).
    Ptp {
        /// The command as given, with operands resolved to values.
        cmd: MovePtp,
        /// Parameters.
        params: MoveParams,
        /// Target window.
        window: f64,
        /// Handle.
        handle: HandleId,
    },
    /// A velocity move.
    Velocity {
        /// The command.
        cmd: MoveVelocity,
        /// Parameters.
        params: MoveParams,
        /// Handle.
        handle: HandleId,
    },
}

impl Queued {
    /// The handle of the queued command.
    pub const fn handle(&self) -> HandleId {
        match self {
            Queued::Ptp { handle, .. } | Queued::Velocity { handle, .. } => *handle,
        }
    }

    /// How it joins the move before it.
    pub const fn buffer(&self) -> BufferMode {
        match self {
            Queued::Ptp { cmd, .. } => cmd.buffer,
            Queued::Velocity { cmd, .. } => cmd.buffer,
        }
    }
}

/// How many moves may wait behind the running one.
pub const QUEUE_CAPACITY: usize = 8;

/// The queue had no room.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QueueFull;

/// A fixed-capacity FIFO of queued moves (no allocation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Queue {
    items: [Option<Queued>; QUEUE_CAPACITY],
    len: usize,
}

impl Default for Queue {
    fn default() -> Self {
        Self {
            items: [None; QUEUE_CAPACITY],
            len: 0,
        }
    }
}

impl Queue {
    /// Appends; `Err(())` when full (the caller still holds the item).
    pub fn push(&mut self, q: Queued) -> Result<(), QueueFull> {
        match self.items.get_mut(self.len) {
            Some(slot) => {
                *slot = Some(q);
                self.len += 1;
                Ok(())
            }
            None => Err(QueueFull),
        }
    }

    /// Removes the first item.
    pub fn pop(&mut self) -> Option<Queued> {
        let first = self.items.first().copied().flatten()?;
        self.items.rotate_left(1);
        if let Some(last) = self.items.last_mut() {
            *last = None;
        }
        self.len -= 1;
        Some(first)
    }

    /// The first item.
    pub fn front(&self) -> Option<&Queued> {
        self.items.first().and_then(Option::as_ref)
    }

    /// The last item.
    pub fn back(&self) -> Option<&Queued> {
        self.len
            .checked_sub(1)
            .and_then(|i| self.items.get(i))
            .and_then(Option::as_ref)
    }

    /// Number of waiting moves.
    pub const fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing waits.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Empties the queue, calling `f` for each removed item.
    pub fn drain(&mut self, mut f: impl FnMut(Queued)) {
        while let Some(q) = self.pop() {
            f(q);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn epoch_later_normalises_and_elapsed_is_exact_on_ticks() {
        let dt = 0.001;
        let e = Epoch::at(10).later(0.0025, dt);
        assert_eq!(e.tick, 12);
        assert!((e.offset_s - 0.0005).abs() < 1e-15);
        assert!((e.elapsed(13, dt) - 0.0005).abs() < 1e-15);
        let far = Epoch::at(0);
        assert_eq!(far.elapsed(1_000_000_000, 0.000_25), 250_000.0);
    }

    #[test]
    fn queue_is_fifo_and_bounded() {
        let mut q = Queue::default();
        let item = |i| Queued::Velocity {
            cmd: MoveVelocity::new(MoveDirection::Positive, 1.0),
            params: MoveParams {
                limits: Limits {
                    vmax: 1.0,
                    amax: 1.0,
                    dmax: 1.0,
                    jmax: 1.0,
                },
                ramp: RampType::Trapezoid,
            },
            handle: HandleId(i),
        };
        for i in 0..QUEUE_CAPACITY as u64 {
            q.push(item(i)).unwrap();
        }
        assert!(q.push(item(99)).is_err());
        assert_eq!(q.back().map(Queued::handle), Some(HandleId(7)));
        assert_eq!(q.pop().map(|x| x.handle()), Some(HandleId(0)));
        assert_eq!(q.front().map(Queued::handle), Some(HandleId(1)));
        assert_eq!(q.len(), QUEUE_CAPACITY - 1);
    }
}
