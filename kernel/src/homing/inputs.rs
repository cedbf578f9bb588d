//! Switch inputs and touch-probe latches as the kernel sees them (issue 13 §1).
//!
//! The layer below (drive layer: CiA 402 0x60FD digital inputs, 0x60B8–0x60BD touch probe;
//! or an I/O module on the bus) resolves polarity — a normally closed limit switch reads
//! "active" when its contact opens — so the kernel only sees "active". Latch positions are
//! in the drive frame (the frame of [`crate::axis::AxisFeedback::position`]); the axis adds
//! its SetPosition offset.

/// The switches of one axis, each already resolved to "active" (polarity handled below).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SwitchInputs {
    /// The negative hardware limit switch is active (0x60FD bit 0).
    pub negative_limit: bool,
    /// The positive hardware limit switch is active (0x60FD bit 1).
    pub positive_limit: bool,
    /// The reference (home) switch is active (0x60FD bit 2).
    pub reference: bool,
}

impl SwitchInputs {
    /// Whether the limit switch in direction `sign` (> 0: positive, < 0: negative) is
    /// active; `false` for `sign == 0`.
    pub fn limit_towards(&self, sign: f64) -> bool {
        if sign > 0.0 {
            self.positive_limit
        } else if sign < 0.0 {
            self.negative_limit
        } else {
            false
        }
    }
}

/// One touch-probe latch channel edge: the position the drive latched and whether this
/// cycle brought a new latch (CiA 402 0x60B9 toggles a bit per new latch; the layer below
/// turns the toggle into this flag, true for exactly one cycle per latch).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Latch {
    /// Latched position (drive frame, units).
    pub position: f64,
    /// The latch is new in this cycle.
    pub new: bool,
}

impl Latch {
    /// A new latch at `position`.
    pub const fn at(position: f64) -> Self {
        Self {
            position,
            new: true,
        }
    }
}

/// Touch-probe latches of one axis (CiA 402 touch probe 1 on its input: 0x60BA positive
/// edge, 0x60BB negative edge; touch probe 2 on the encoder's zero pulse: 0x60BC).
///
/// The probe input is the reference switch — or, for homing on a limit switch
/// (`SwitchConfig::LimitSwitch`), the limit switch the drive's touch-probe source (vendor
/// object 0x60D0) is set to: the kernel takes edge *positions* only from these latches,
/// never from the cycle-sampled position, so a reference is exact at any speed and cycle
/// time (issue 13 §2).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProbeLatches {
    /// Position latched on the rising edge of the probe input (becoming active).
    pub rising: Latch,
    /// Position latched on the falling edge of the probe input (becoming inactive).
    pub falling: Latch,
    /// Position latched on the encoder's index (zero) pulse.
    pub index: Latch,
}

impl ProbeLatches {
    /// The latches shifted by `offset` (drive frame → axis frame).
    pub fn shifted(self, offset: f64) -> Self {
        let s = |l: Latch| Latch {
            position: l.position + offset,
            new: l.new,
        };
        Self {
            rising: s(self.rising),
            falling: s(self.falling),
            index: s(self.index),
        }
    }
}

/// Which end of the axis a limit switch guards.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LimitSide {
    /// The negative end.
    Negative,
    /// The positive end.
    Positive,
}

impl LimitSide {
    /// The side in direction `sign` (> 0: positive).
    pub fn towards(sign: f64) -> Self {
        if sign > 0.0 {
            Self::Positive
        } else {
            Self::Negative
        }
    }

    /// +1 or −1.
    pub const fn sign(self) -> f64 {
        match self {
            Self::Negative => -1.0,
            Self::Positive => 1.0,
        }
    }

    /// "negative" or "positive".
    pub const fn name(self) -> &'static str {
        match self {
            Self::Negative => "negative",
            Self::Positive => "positive",
        }
    }
}

impl core::fmt::Display for LimitSide {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{} limit switch", self.name())
    }
}
