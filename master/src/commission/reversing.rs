//! The reversing test motion (seed 000 §5.2.6.4 往返运动): point-to-point moves back and
//! forth between two positions, as a commissioning engineer runs to tune the loops. The
//! seed notes there is no separate mode for it — it is MovePtp to one end and back — so it
//! is exactly that: absolute moves with the axis' last-used PTP parameters (or the speed
//! given), each waited for, `cycles` times there and back, starting with a move to `from`.
//! On a modulo axis both ends lie within the period and the moves go the way the numbers
//! do (from 10° to 350°: 340° forwards, and back), never the short way across the wrap.

use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode};

use super::{CommissionError, Context, ProcedureOutcome};

/// The reversing motion's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reversing {
    /// One end (units); the motion starts by moving here.
    pub from: f64,
    /// The other end (units).
    pub to: f64,
    /// Cycles: `from` → `to` → `from`, this many times (≥ 1).
    pub cycles: u32,
    /// Speed (units/s); `None`: the axis' last-used.
    pub speed: Option<f64>,
    /// The axis' modulo period (units), if it has one.
    pub modulo: Option<f64>,
}

impl Reversing {
    /// Checks the operands, naming the first that is wrong (`--from`, `--to`, …).
    pub fn check(&self, axis: &str) -> Result<(), CommissionError> {
        let bad = |operand: &'static str, reason: String| CommissionError::Operand {
            axis: axis.to_string(),
            procedure: "reversing",
            operand,
            reason,
        };
        if !self.from.is_finite() {
            return Err(bad("--from", format!("{} is not a position", self.from)));
        }
        if !self.to.is_finite() {
            return Err(bad("--to", format!("{} is not a position", self.to)));
        }
        if let Some(period) = self.modulo {
            for (operand, v) in [("--from", self.from), ("--to", self.to)] {
                if !(0.0..period).contains(&v) {
                    return Err(bad(
                        operand,
                        format!("{v} is not within the modulo period [0, {period})"),
                    ));
                }
            }
        }
        if self.from == self.to {
            return Err(bad(
                "--to",
                format!("{} is --from: there is nothing to reverse between", self.to),
            ));
        }
        if self.cycles == 0 {
            return Err(bad("--cycles", "must be at least 1".into()));
        }
        if let Some(v) = self.speed {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad("--speed", format!("{v} must be > 0")));
            }
        }
        Ok(())
    }
}

/// Runs it (see the module doc).
pub(crate) fn run(cx: &Context, r: Reversing) -> Result<ProcedureOutcome, CommissionError> {
    r.check(&cx.name)?;
    let moves = 1 + 2 * u64::from(r.cycles);
    let mut done = 0u64;
    // A modulo axis goes the way the numbers do: towards `to` in the direction from
    // `from`, and back the other way.
    let mode = |target: f64| match r.modulo {
        None => PositioningMode::AbsNormal,
        Some(_) if (target == r.to) == (r.to > r.from) => PositioningMode::AbsModuloPos,
        Some(_) => PositioningMode::AbsModuloNeg,
    };
    let go = |target: f64, done: &mut u64, what: &str| {
        let mut m = MovePtp::new(mode(target), target);
        m.speed = r.speed;
        let h = cx.command(Command::MovePtp(m))?;
        let cycles_done = done.saturating_sub(1) / 2;
        let when = || format!("after {cycles_done} of {} cycles", r.cycles);
        let base = *done as f64 / moves as f64;
        cx.follow(&h, "MovePtp", when, |cx| {
            cx.progress(what, base);
        })?;
        *done += 1;
        Ok::<(), CommissionError>(())
    };
    go(r.from, &mut done, "moving to the start")?;
    for c in 0..r.cycles {
        let there = format!("cycle {} of {}: to {}", c + 1, r.cycles, r.to);
        go(r.to, &mut done, &there)?;
        let back = format!("cycle {} of {}: back to {}", c + 1, r.cycles, r.from);
        go(r.from, &mut done, &back)?;
    }
    cx.progress("done", 1.0);
    Ok(ProcedureOutcome::Reversing { cycles: r.cycles })
}
