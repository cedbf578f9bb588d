//! What a run must end with, from the layout and the seeds' definitions alone (not from
//! the kernel's own goals).

use super::Layout;
use gantry_kernel::homing::{
    HomeDirection, HomingMode, LimitSide, MoveHome, SwitchConfig, SwitchMode,
};

/// What the seed says a run ends on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Expect {
    /// The edge at `at`, crossed moving `moving` (±1).
    Edge { at: f64, moving: f64 },
    /// At once, where the axis stands (mcOn on the cam, mcOff off it, seed 003).
    AtOnce,
}

/// The seed's definitions, written out per mode (not derived from the kernel's goals).
pub fn expected(layout: &Layout, mode: SwitchMode, dir: HomeDirection, start: &str) -> Expect {
    let (low, high) = layout.cam;
    let d = dir.sign();
    let rising_side = |m: f64| if m > 0.0 { low } else { high };
    let falling_side = |m: f64| if m > 0.0 { high } else { low };
    let edge = |at, moving| Expect::Edge { at, moving };
    use HomeDirection as D;
    match mode {
        // "Ends on the rising edge in the set direction" (reverses when it passes it the
        // other way), and so on for the three others.
        SwitchMode::RisingEdge => edge(rising_side(d), d),
        SwitchMode::FallingEdge => edge(falling_side(d), d),
        SwitchMode::RisingEdgeInverse => edge(rising_side(-d), -d),
        SwitchMode::FallingEdgeInverse => edge(falling_side(-d), -d),
        // "Always the left edge; ① ends moving positive, ② and ③ moving negative."
        SwitchMode::EdgeSwitchPositive => edge(low, if start == "1" { 1.0 } else { -1.0 }),
        // "Always the right edge; ① and ② end moving positive, ③ moving negative."
        SwitchMode::EdgeSwitchNegative => edge(high, if start == "3" { -1.0 } else { 1.0 }),
        // mcOn: ends when the signal is on.
        SwitchMode::On => match (start, dir) {
            ("1", _) => edge(low, 1.0),
            ("3", _) => edge(high, -1.0),
            (_, D::Positive | D::Negative) => Expect::AtOnce,
            (_, D::SwitchPositive) => edge(low, 1.0),
            (_, D::SwitchNegative) => edge(high, -1.0),
        },
        // mcOff: ends when the signal is off.
        SwitchMode::Off => match (start, dir) {
            ("1" | "3", _) => Expect::AtOnce,
            (_, D::Positive) => edge(high, 1.0),
            (_, D::Negative) => edge(low, -1.0),
            (_, D::SwitchPositive) => edge(low, -1.0),
            (_, D::SwitchNegative) => edge(high, 1.0),
        },
    }
}

/// What the run must end with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MoveHomeExpect {
    /// The reference (drive frame) is here.
    Reference(f64),
    /// Refused at the call.
    Refused,
    /// Stopped by this limit switch (RefSwitch with the cam behind the start).
    Limit(LimitSide),
}

/// The reference from the layout and the seed's definitions (see `homing::move_home`).
pub fn expected_move_home(l: &Layout, p: &MoveHome, x0: f64) -> MoveHomeExpect {
    let d = p.direction.sign();
    let edge = match p.switch_config {
        SwitchConfig::LimitSwitch => {
            if d > 0.0 {
                l.positive_limit
            } else {
                l.negative_limit
            }
        }
        _ => {
            if d > 0.0 {
                l.cam.0
            } else {
                l.cam.1
            }
        }
    };
    let zero_pulse = matches!(
        p.mode,
        HomingMode::ZeroPulse1Phase | HomingMode::ZeroPulse2Phase
    );
    match p.switch_config {
        SwitchConfig::NoSwitch if !zero_pulse => MoveHomeExpect::Refused,
        SwitchConfig::NoSwitch => MoveHomeExpect::Reference(if d > 0.0 {
            l.index_above(x0)
        } else {
            l.index_below(x0)
        }),
        SwitchConfig::RefSwitch if (d > 0.0 && x0 > l.cam.1) || (d < 0.0 && x0 < l.cam.0) => {
            MoveHomeExpect::Limit(LimitSide::towards(d))
        }
        _ if zero_pulse => MoveHomeExpect::Reference(if d > 0.0 {
            l.index_below(edge)
        } else {
            l.index_above(edge)
        }),
        _ => MoveHomeExpect::Reference(edge),
    }
}
