//! The control protocol: JSON lines over a Unix socket, versioned. One request per line,
//! one reply per line:
//!
//! ```text
//! → {"v":1,"cmd":"move","axis":"x","to":100.0,"speed":50.0}
//! ← {"v":1,"ok":true,"result":{"handle":7}}
//! → {"v":1,"cmd":"wait","handle":7,"timeout_s":10}
//! ← {"v":1,"ok":true,"result":{"status":"Done"}}
//! → {"v":1,"cmd":"frobnicate"}
//! ← {"v":1,"ok":false,"error":"invalid request: unknown variant `frobnicate`, expected one of …"}
//! ```
//!
//! Commands: `status`, `enable`, `disable`, `move`, `jog`, `gear`, `gear_out`, `cam`,
//! `cam_out`, `halt`, `stop`, `release`,
//! `set_position`, `reset`, `home`, `commission` (a commissioning procedure), `procedure` (its
//! progress), `command` (status of a handle), `wait`, `trace`, `sdo`, `shutdown`. A malformed or
//! hostile request gets an error reply; nothing of it reaches the cycle thread.
//!
//! [`Request`] is the one description of a request: the CLI serialises it
//! ([`Request::to_line`]), the server parses it ([`parse`]). The words of the modes, buffer
//! modes, transition modes and jog directions are typed ([`MoveMode`], [`BufferMode`],
//! [`TransitionMode`], [`JogDirection`]),
//! each with one table of its wire names; a wrong word is refused at parsing with the field,
//! the word and the choices. The wire format is version 1 as before: the same fields and
//! words, `null` still means "not given".

use std::fmt;
use std::marker::PhantomData;
use std::str::FromStr;

use serde::de::{self, Deserializer, Visitor};
use serde::{Deserialize, Serialize, Serializer};
use serde_json::Value;
use thiserror::Error;

/// The protocol version this gantry speaks.
pub const VERSION: u64 = 1;
/// Longest request line accepted, besides an `sdo` download's data ([`max_line`]).
pub const MAX_LINE: usize = 64 * 1024;

/// Longest request line accepted when an SDO transfer carries up to `sdo_max_bytes`:
/// [`MAX_LINE`], or room for that many bytes as hex digits and the rest of the request.
pub const fn max_line(sdo_max_bytes: usize) -> usize {
    let sdo = 2 * sdo_max_bytes + 1024;
    if sdo > MAX_LINE {
        sdo
    } else {
        MAX_LINE
    }
}

/// A word of the protocol that is not one of its field's choices.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("{field} {value:?} is not one of {choices}")]
pub struct BadWord {
    /// The request's field (`mode`, `buffer`, `direction`).
    pub field: &'static str,
    /// What was sent.
    pub value: String,
    /// The words it takes.
    pub choices: String,
}

/// A protocol enum: one table of wire names per type, the canonical name first and
/// aliases after it; serde, [`FromStr`] and [`fmt::Display`] all read it.
pub trait Word: Copy + PartialEq + 'static {
    /// The request field it fills (named in errors).
    const FIELD: &'static str;
    /// Wire names and the value each stands for.
    const NAMES: &'static [(&'static str, Self)];

    /// The canonical wire name.
    fn name(self) -> &'static str {
        Self::NAMES
            .iter()
            .find(|(_, v)| *v == self)
            .map_or("?", |(n, _)| n)
    }

    /// The words this field takes, for messages.
    fn choices() -> String {
        let names: Vec<String> = Self::NAMES.iter().map(|(n, _)| format!("{n:?}")).collect();
        names.join(", ")
    }

    /// The value of a wire name.
    fn from_word(word: &str) -> Result<Self, BadWord> {
        Self::NAMES
            .iter()
            .find(|(n, _)| *n == word)
            .map(|(_, v)| *v)
            .ok_or_else(|| BadWord {
                field: Self::FIELD,
                value: word.to_string(),
                choices: Self::choices(),
            })
    }
}

/// Reads a [`Word`] from a string; a wrong type or word names the field.
struct WordVisitor<T>(PhantomData<T>);

impl<T: Word> Visitor<'_> for WordVisitor<T> {
    type Value = T;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{} as one of {}", T::FIELD, T::choices())
    }

    fn visit_str<E: de::Error>(self, word: &str) -> Result<T, E> {
        T::from_word(word).map_err(E::custom)
    }
}

/// Serde, `FromStr` and `Display` of a [`Word`] type, from its table.
macro_rules! word_impls {
    ($t:ty) => {
        impl Serialize for $t {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(self.name())
            }
        }
        impl<'de> Deserialize<'de> for $t {
            fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                d.deserialize_str(WordVisitor(PhantomData))
            }
        }
        impl FromStr for $t {
            type Err = BadWord;
            fn from_str(word: &str) -> Result<Self, BadWord> {
                Self::from_word(word)
            }
        }
        impl fmt::Display for $t {
            fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(self.name())
            }
        }
    };
}

/// MoveHome's parameters as a `home` request carries them (`"params": {…}`); each one
/// left out is the axis' saved value (the last call's; the service keeps the whole set in
/// the axis' parameter file, `persist`, so it holds across restarts).
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct HomeParams {
    /// Search direction.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direction: Option<JogDirection>,
    /// What the search uses.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub switches: Option<HomeSwitches>,
    /// What the reference is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mode: Option<HomeMode>,
    /// Speed of the switch search (units/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_switch: Option<f64>,
    /// Longest switch search (units).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_distance_switch: Option<f64>,
    /// Speed of the reference search (units/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_reference: Option<f64>,
    /// Longest reference search (units).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_distance_reference: Option<f64>,
    /// Acceleration (units/s²).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acceleration: Option<f64>,
    /// Jerk (units/s³).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jerk: Option<f64>,
    /// The position the reference gets (units).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_offset: Option<f64>,
    /// Where the axis goes after homing (units).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal_position: Option<f64>,
}

/// Beckhoff step-to-absolute-switch's parameters (MC_StepAbsoluteSwitch: search the
/// reference cam, reversing at the limit switches) as a `home` request carries them
/// (`"step_switch": {…}`); each one left out is the axis' saved value (the last such
/// call's), else its default: the axis' default acceleration, deceleration and jerk, a
/// set position of 0 and no distance limit. Direction, switch mode and velocity have no
/// default: the axis' first step-to-switch call names them.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StepSwitchParams {
    /// How the run starts (Direction).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direction: Option<StepDirection>,
    /// Which crossing of the cam ends it (SwitchMode).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub switch_mode: Option<StepSwitchMode>,
    /// Search speed (Velocity, units/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<f64>,
    /// Acceleration (units/s²).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acceleration: Option<f64>,
    /// Deceleration (units/s²): also how hard the search reverses.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deceleration: Option<f64>,
    /// Jerk (units/s³).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jerk: Option<f64>,
    /// The position the cam's edge gets (SetPosition, units).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub set_position: Option<f64>,
    /// Farthest the search may travel (DistanceLimit, units).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distance_limit: Option<f64>,
}

/// Drive homing's parameters as a `drive_home` request carries them (`"params": {…}`);
/// each one left out is the axis' `[axis.drive_homing]` value.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DriveHomeParams {
    /// CiA 402 homing method (0x6098).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub method: Option<i8>,
    /// Speed during search for switch (units/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_switch: Option<f64>,
    /// Speed during search for zero (units/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_zero: Option<f64>,
    /// Homing acceleration (units/s²).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acceleration: Option<f64>,
    /// Home offset (units; the home position reads as minus this).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub home_offset: Option<f64>,
    /// How long the drive may take to report homing attained (s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub timeout_s: Option<f64>,
    /// Skip the drive's homing run (an absolute drive): homed where it stands.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skip: Option<bool>,
}

/// How a move's `to` is meant. What `absolute` means depends on the axis: on a modulo axis
/// it takes the shorter way round.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MoveMode {
    /// `to` is a position (on a modulo axis: reached the shorter way round).
    #[default]
    Absolute,
    /// `to` is a distance from the set position.
    Relative,
    /// Modulo axes only: the shorter way round (as `absolute` there).
    Shortest,
    /// Modulo axes only: round in the positive direction.
    Positive,
    /// Modulo axes only: round in the negative direction.
    Negative,
}

/// What a homing run searches with (Jetter MoveHome `SwitchConfiguration`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomeSwitches {
    /// The index pulse only.
    None,
    /// The reference switch; a limit switch reached reverses the search.
    RefAndLimit,
    /// The reference switch only: a limit switch is an error.
    Ref,
    /// The limit switch in the search direction is the reference.
    Limit,
}

impl Word for HomeSwitches {
    const FIELD: &'static str = "switches";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("none", Self::None),
        ("ref-and-limit", Self::RefAndLimit),
        ("ref", Self::Ref),
        ("limit", Self::Limit),
    ];
}
word_impls!(HomeSwitches);

/// How a step-to-absolute-switch run starts (Beckhoff MC_Home_Direction).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepDirection {
    /// Start positive, reversing at a limit switch (mcPositiveDirection).
    Positive,
    /// Start negative (mcNegativeDirection).
    Negative,
    /// Off the cam start positive; on it first leave it negative (mcSwitchPositive).
    SwitchPositive,
    /// Off the cam start negative; on it first leave it positive (mcSwitchNegative).
    SwitchNegative,
}

impl Word for StepDirection {
    const FIELD: &'static str = "direction";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("positive", Self::Positive),
        ("negative", Self::Negative),
        ("switch-positive", Self::SwitchPositive),
        ("switch-negative", Self::SwitchNegative),
        ("+", Self::Positive),
        ("-", Self::Negative),
    ];
}
word_impls!(StepDirection);

/// Which crossing of the cam ends a step-to-absolute-switch run (Beckhoff MC_Switch_Mode).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepSwitchMode {
    /// Where the cam signal is on (mcOn).
    On,
    /// Where the cam signal is off (mcOff).
    Off,
    /// The rising edge, moving in the set direction (mcRisingEdge).
    RisingEdge,
    /// The falling edge, moving in the set direction (mcFallingEdge).
    FallingEdge,
    /// The rising edge, moving against the set direction (mcRisingEdgeInverse).
    RisingEdgeInverse,
    /// The falling edge, moving against the set direction (mcFallingEdgeInverse).
    FallingEdgeInverse,
    /// The cam's negative edge, whichever way (mcEdgeSwitchPositive).
    EdgeSwitchPositive,
    /// The cam's positive edge, whichever way (mcEdgeSwitchNegative).
    EdgeSwitchNegative,
}

impl Word for StepSwitchMode {
    const FIELD: &'static str = "switch_mode";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("on", Self::On),
        ("off", Self::Off),
        ("rising-edge", Self::RisingEdge),
        ("falling-edge", Self::FallingEdge),
        ("rising-edge-inverse", Self::RisingEdgeInverse),
        ("falling-edge-inverse", Self::FallingEdgeInverse),
        ("edge-switch-positive", Self::EdgeSwitchPositive),
        ("edge-switch-negative", Self::EdgeSwitchNegative),
    ];
}
word_impls!(StepSwitchMode);

/// Which homing run the master does (a `home` request's, the axis' last one).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HomeMethod {
    /// Jetter MoveHome.
    #[default]
    MoveHome,
    /// Beckhoff step-to-absolute-switch (MC_StepAbsoluteSwitch).
    StepToSwitch,
}

impl Word for HomeMethod {
    const FIELD: &'static str = "home_method";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("move-home", Self::MoveHome),
        ("step-to-switch", Self::StepToSwitch),
    ];
}
word_impls!(HomeMethod);

/// Which commissioning procedure a `commission` request runs (seed 000 §5.2.6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommissionKind {
    /// Measure the commutation offset (dynamic mode) and write it to the drive.
    Commutation,
    /// The reversing test motion between `from` and `to`.
    Reversing,
}

impl Word for CommissionKind {
    const FIELD: &'static str = "procedure";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("commutation", Self::Commutation),
        ("reversing", Self::Reversing),
    ];
}
word_impls!(CommissionKind);

/// What a homing run takes as the reference, in how many phases (Jetter MoveHome
/// `ReferencingMode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomeMode {
    /// The switch edge, searched slowly.
    Edge,
    /// The switch fast, then its edge slowly.
    Edge2,
    /// The index pulse, searched slowly.
    ZeroPulse,
    /// The switch fast, then the index pulse slowly.
    ZeroPulse2,
}

impl Word for HomeMode {
    const FIELD: &'static str = "mode";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("edge", Self::Edge),
        ("edge-2", Self::Edge2),
        ("zero-pulse", Self::ZeroPulse),
        ("zero-pulse-2", Self::ZeroPulse2),
    ];
}
word_impls!(HomeMode);

impl Word for MoveMode {
    const FIELD: &'static str = "mode";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("absolute", Self::Absolute),
        ("relative", Self::Relative),
        ("shortest", Self::Shortest),
        ("positive", Self::Positive),
        ("negative", Self::Negative),
    ];
}
word_impls!(MoveMode);

/// How a move takes over from the one in progress (PLCopen's buffer modes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BufferMode {
    /// Replaces the move in progress at once.
    #[default]
    Aborting,
    /// Starts when the move in progress is done.
    Buffered,
    /// Blends at the lower of the two speeds.
    BlendingLow,
    /// Blends at the speed of the move in progress.
    BlendingPrevious,
    /// Blends at the speed of the new move.
    BlendingNext,
    /// Blends at the higher of the two speeds.
    BlendingHigh,
}

impl Word for BufferMode {
    const FIELD: &'static str = "buffer";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("aborting", Self::Aborting),
        ("buffered", Self::Buffered),
        ("blending-low", Self::BlendingLow),
        ("blending-previous", Self::BlendingPrevious),
        ("blending-next", Self::BlendingNext),
        ("blending-high", Self::BlendingHigh),
    ];
}
word_impls!(BufferMode);

/// Which way a jog goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JogDirection {
    /// Increasing positions: `"+"` (or `"positive"`).
    Positive,
    /// Decreasing positions: `"-"` (or `"negative"`).
    Negative,
}

impl Word for JogDirection {
    const FIELD: &'static str = "direction";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("+", Self::Positive),
        ("-", Self::Negative),
        ("positive", Self::Positive),
        ("negative", Self::Negative),
    ];
}
word_impls!(JogDirection);

/// Which of a master's values a follower follows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MasterSource {
    /// Its set values.
    #[default]
    Set,
    /// Its actual values (its encoder).
    Actual,
}

impl Word for MasterSource {
    const FIELD: &'static str = "source";
    const NAMES: &'static [(&'static str, Self)] = &[("set", Self::Set), ("actual", Self::Actual)];
}
word_impls!(MasterSource);

/// How a cam is placed (PLCopen MC_CamIn's start mode).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CamStartMode {
    /// The table's axes are the master's and the follower's positions.
    #[default]
    Absolute,
    /// The table starts where the master is and adds to the follower's position.
    Relative,
}

impl Word for CamStartMode {
    const FIELD: &'static str = "start";
    const NAMES: &'static [(&'static str, Self)] =
        &[("absolute", Self::Absolute), ("relative", Self::Relative)];
}
word_impls!(CamStartMode);

/// When a master-driven jog follows its master (Logix MAJ Lock Direction).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LockDirection {
    /// Both ways, from the start.
    #[default]
    None,
    /// From the start, while the master moves forward.
    ImmediateForward,
    /// From the start, while the master moves backwards.
    ImmediateReverse,
    /// Once the master crosses the lock position forward, then while it moves forward.
    PositionForward,
    /// Once the master crosses the lock position backwards, then while it moves so.
    PositionReverse,
}

impl Word for LockDirection {
    const FIELD: &'static str = "lock";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("none", Self::None),
        ("immediate-forward", Self::ImmediateForward),
        ("immediate-reverse", Self::ImmediateReverse),
        ("position-forward", Self::PositionForward),
        ("position-reverse", Self::PositionReverse),
    ];
}
word_impls!(LockDirection);

/// What a `group` request does to an axis group.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroupOp {
    /// MC_GroupEnable.
    Enable,
    /// MC_GroupDisable.
    Disable,
    /// MC_GroupStop (brakes along the path, locks until released).
    Stop,
    /// MC_GroupHalt (brakes along the path to GroupStandby, no lock).
    Halt,
    /// MC_GroupHome (every axis runs its configured homing, together).
    Home,
    /// MC_GroupStop's Execute falling.
    Release,
    /// MC_GroupReset.
    Reset,
}

impl Word for GroupOp {
    const FIELD: &'static str = "op";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("enable", Self::Enable),
        ("disable", Self::Disable),
        ("stop", Self::Stop),
        ("halt", Self::Halt),
        ("home", Self::Home),
        ("release", Self::Release),
        ("reset", Self::Reset),
    ];
}
word_impls!(GroupOp);

/// How a circular move's aux point is meant (Omron CircMode).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CircularMode {
    /// A point the arc passes through.
    Border,
    /// The center.
    Center,
    /// `[radius, _]`: negative for the long arc.
    Radius,
}

impl Word for CircularMode {
    const FIELD: &'static str = "mode";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("border", Self::Border),
        ("center", Self::Center),
        ("radius", Self::Radius),
    ];
}
word_impls!(CircularMode);

/// Which way round a circular move goes (Omron PathChoice).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CircularDirection {
    /// Counter-clockwise.
    #[default]
    Ccw,
    /// Clockwise.
    Cw,
}

impl Word for CircularDirection {
    const FIELD: &'static str = "direction";
    const NAMES: &'static [(&'static str, Self)] = &[("ccw", Self::Ccw), ("cw", Self::Cw)];
}
word_impls!(CircularDirection);

/// How a blended junction of two group moves may leave the programmed path (PLCopen
/// Part 4 TransitionMode).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TransitionMode {
    /// The path goes through the junction: blended in motion only where two lines are
    /// collinear, elsewhere passed at rest.
    #[default]
    None,
    /// The next move starts while the one before ends: the corner is rounded, within the
    /// move's `corner_deviation`.
    CornerSuperimposed,
}

impl Word for TransitionMode {
    const FIELD: &'static str = "transition";
    const NAMES: &'static [(&'static str, Self)] = &[
        ("none", Self::None),
        ("corner-superimposed", Self::CornerSuperimposed),
    ];
}
word_impls!(TransitionMode);

/// Which way an SDO transfer goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoDirection {
    /// Read the object from the drive.
    Upload,
    /// Write the object to the drive.
    Download,
}

impl Word for SdoDirection {
    const FIELD: &'static str = "direction";
    const NAMES: &'static [(&'static str, Self)] =
        &[("upload", Self::Upload), ("download", Self::Download)];
}
word_impls!(SdoDirection);

/// `null` is the default, as an absent field is (version-1 clients send `"buffer": null`).
fn null_is_default<'de, D, T>(d: D) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de> + Default,
{
    Ok(Option::<T>::deserialize(d)?.unwrap_or_default())
}

/// A request.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(tag = "cmd", rename_all = "snake_case", deny_unknown_fields)]
pub enum Request {
    /// Axes, drives, bus and cycle figures.
    Status,
    /// Power on.
    Enable {
        /// Axis name.
        axis: String,
    },
    /// Power off (stopping first).
    Disable {
        /// Axis name.
        axis: String,
    },
    /// A point-to-point move.
    Move {
        /// Axis name.
        axis: String,
        /// Target (absolute) or distance (relative), in the axis' units.
        to: f64,
        /// How `to` is meant (default `absolute`).
        #[serde(default, deserialize_with = "null_is_default")]
        mode: MoveMode,
        /// Speed (units/s; default: the axis').
        #[serde(default, skip_serializing_if = "Option::is_none")]
        speed: Option<f64>,
        /// Acceleration (units/s²).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        acceleration: Option<f64>,
        /// Deceleration (units/s²).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        deceleration: Option<f64>,
        /// Jerk (units/s³).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        jerk: Option<f64>,
        /// How it takes over from the move in progress (default `aborting`).
        #[serde(default, deserialize_with = "null_is_default")]
        buffer: BufferMode,
    },
    /// Jog until halted. With `master`, a master-driven jog (Logix MAJ with MDAC): the
    /// speed is in the axis' units per master unit, and `lock` / `lock_position` say when
    /// it follows.
    Jog {
        /// Axis name.
        axis: String,
        /// Which way.
        direction: JogDirection,
        /// Speed (units/s; with `master`, units per master unit).
        speed: f64,
        /// The master that drives the jog.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        master: Option<String>,
        /// When it follows (default `none`: both ways from the start).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        lock: Option<LockDirection>,
        /// Master position of the `position-*` locks.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        lock_position: Option<f64>,
    },
    /// Follow a master at `numerator / denominator` (PLCopen MC_GearIn); with
    /// `master_sync_position` and `slave_sync_position`, in sync at those positions
    /// (MC_GearInPos). Catch-up dynamics left out are the axis' defaults.
    Gear {
        /// Axis name (the follower).
        axis: String,
        /// The master's name.
        master: String,
        /// Ratio numerator (negative: the other way).
        numerator: i32,
        /// Ratio denominator (> 0).
        denominator: u32,
        /// The master's set or actual values (default `set`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        source: Option<MasterSource>,
        /// Catch-up acceleration (units/s²).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        acceleration: Option<f64>,
        /// Catch-up deceleration (units/s²).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        deceleration: Option<f64>,
        /// Catch-up jerk (units/s³).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        jerk: Option<f64>,
        /// GearInPos: the master's position where the follower is in sync.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        master_sync_position: Option<f64>,
        /// GearInPos: the follower's position there.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        slave_sync_position: Option<f64>,
        /// GearInPos: master distance before its sync position over which the follower
        /// catches up (default: from where the master is).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        master_start_distance: Option<f64>,
    },
    /// MC_GroupEnable, MC_GroupDisable, MC_GroupStop (and its release), MC_GroupReset.
    Group {
        /// The group's name.
        group: String,
        /// What to do.
        op: GroupOp,
    },
    /// MC_MoveLinear of a group: to `to` (A0..), at `velocity` along the path.
    MoveLinear {
        /// The group's name.
        group: String,
        /// Target (or distance with `relative`) of each of the group's axes, A0 first.
        to: Vec<f64>,
        /// Path velocity (units/s, required).
        velocity: f64,
        /// Path acceleration (default: the axes' limits decide).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        acceleration: Option<f64>,
        /// Path deceleration.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        deceleration: Option<f64>,
        /// Path jerk.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        jerk: Option<f64>,
        /// `to` is a distance from where the move starts.
        #[serde(default)]
        relative: bool,
        /// How it joins the group's running move (default `aborting`; the words of
        /// `move`'s `buffer`).
        #[serde(default, deserialize_with = "null_is_default")]
        buffer: BufferMode,
        /// How a blended junction may leave the path (default `none`).
        #[serde(default, deserialize_with = "null_is_default")]
        transition: TransitionMode,
        /// With `corner-superimposed`: how far the path may pass from the corner (units,
        /// > 0; default the group's `corner_deviation`, else the axes' limits decide).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        corner_deviation: Option<f64>,
    },
    /// MC_MoveCircular2D of a group.
    MoveCircular {
        /// The group's name.
        group: String,
        /// How `aux` is meant.
        mode: CircularMode,
        /// Through point, center, or `[radius, 0]`.
        aux: [f64; 2],
        /// End point.
        end: [f64; 2],
        /// Which way round (default ccw; a border arc goes through its point).
        #[serde(default)]
        direction: CircularDirection,
        /// The two circular axes as logical axes of the group (default `[0, 1]`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        axes: Option<[usize; 2]>,
        /// Path velocity (units/s, required).
        velocity: f64,
        /// Path acceleration.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        acceleration: Option<f64>,
        /// Path deceleration.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        deceleration: Option<f64>,
        /// Path jerk.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        jerk: Option<f64>,
        /// `aux` and `end` are relative to where the move starts.
        #[serde(default)]
        relative: bool,
        /// How it joins the group's running move (default `aborting`).
        #[serde(default, deserialize_with = "null_is_default")]
        buffer: BufferMode,
        /// How a blended junction may leave the path (default `none`).
        #[serde(default, deserialize_with = "null_is_default")]
        transition: TransitionMode,
        /// With `corner-superimposed`: how far the path may pass from the corner (units,
        /// > 0; default the group's `corner_deviation`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        corner_deviation: Option<f64>,
    },
    /// Stop gearing (PLCopen MC_GearOut): the axis goes on at its velocity.
    GearOut {
        /// Axis name.
        axis: String,
    },
    /// Follow a master through a cam table (PLCopen MC_CamIn).
    Cam {
        /// Axis name (the follower).
        axis: String,
        /// The master's name.
        master: String,
        /// The cam table's name.
        table: String,
        /// Whether the table repeats (default true).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        periodic: Option<bool>,
        /// Absolute or relative placement (default `absolute`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        start: Option<CamStartMode>,
        /// The master's set or actual values (default `set`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        source: Option<MasterSource>,
        /// Shift of the table's master coordinate.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        master_offset: Option<f64>,
        /// Shift of the follower.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        slave_offset: Option<f64>,
        /// Table master units per master unit (default 1).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        master_scaling: Option<f64>,
        /// Follower units per table slave unit (default 1).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        slave_scaling: Option<f64>,
        /// Catch-up acceleration (units/s²).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        acceleration: Option<f64>,
        /// Catch-up deceleration (units/s²).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        deceleration: Option<f64>,
        /// Catch-up jerk (units/s³).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        jerk: Option<f64>,
    },
    /// Stop camming (PLCopen MC_CamOut): the axis goes on at its velocity.
    CamOut {
        /// Axis name.
        axis: String,
    },
    /// Decelerate to a stop (the axis takes new moves at once).
    Halt {
        /// Axis name.
        axis: String,
    },
    /// Stop and lock the axis until released.
    Stop {
        /// Axis name.
        axis: String,
    },
    /// Release a stopped axis.
    Release {
        /// Axis name.
        axis: String,
    },
    /// Set the axis' position without moving (absolute: marks it homed).
    SetPosition {
        /// Axis name.
        axis: String,
        /// The position the axis is at now.
        position: f64,
    },
    /// A homing run on the axis' switches and its drive's touch probe: Jetter MoveHome
    /// when `params` is given (even `{}`), Beckhoff step-to-absolute-switch when
    /// `step_switch` is; with neither, the axis' last homing run of the two (MoveHome when
    /// it has had none). Every parameter left out is the axis' saved one (see
    /// [`HomeParams`], [`StepSwitchParams`]). The reply names the run's `method`.
    Home {
        /// Axis name.
        axis: String,
        /// MoveHome's parameters.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        params: Option<HomeParams>,
        /// Step-to-absolute-switch's parameters.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        step_switch: Option<StepSwitchParams>,
    },
    /// A commissioning procedure on the axis (`gantry commission`); it runs on in the
    /// service, `procedure` follows it, `stop` on the axis cancels it.
    Commission {
        /// Axis name.
        axis: String,
        /// Which procedure.
        procedure: CommissionKind,
        /// Reversing: one end (units).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        from: Option<f64>,
        /// Reversing: the other end (units).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        to: Option<f64>,
        /// Reversing: cycles there and back.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        cycles: Option<u32>,
        /// Reversing: speed (units/s; default the axis' last-used).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        speed: Option<f64>,
        /// Commutation: current of the vector (per mille of rated; default 300).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        current: Option<u16>,
    },
    /// Where a commissioning procedure is, and how it ended.
    Procedure {
        /// Its id (the `commission` reply's `procedure`).
        id: u64,
    },
    /// Homing done by the axis' drive itself (CiA 402 homing mode), then back in CSP;
    /// every parameter left out is the axis' `[axis.drive_homing]` one.
    DriveHome {
        /// Axis name.
        axis: String,
        /// The parameters.
        #[serde(default)]
        params: DriveHomeParams,
    },
    /// Leave ErrorStop: the slave back to OP if needed, the drive's fault reset.
    Reset {
        /// Axis name.
        axis: String,
    },
    /// The status of a command handle.
    Command {
        /// The handle.
        handle: u64,
    },
    /// Waits until a handle's status is final (or the timeout).
    Wait {
        /// The handle.
        handle: u64,
        /// Seconds to wait at most.
        timeout_s: f64,
    },
    /// Set and actual positions of some axes over the next seconds.
    Trace {
        /// Axis names.
        axes: Vec<String>,
        /// Seconds to record (up to 60).
        seconds: f64,
    },
    /// Read or write an object of a drive (SDO) while the cycle runs; the drive named by
    /// an axis or by its position on the bus (exactly one of the two).
    Sdo {
        /// The axis whose drive it is.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        axis: Option<String>,
        /// Or the drive's position on the bus.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        drive: Option<usize>,
        /// Upload (read) or download (write).
        direction: SdoDirection,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Download: the bytes to write, as hex (two digits a byte, as on the wire).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        data: Option<String>,
        /// Seconds the drive may take (default 2).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        timeout_s: Option<f64>,
    },
    /// What the configuration knows of an object of a drive: its EDS' data type, access
    /// and name (CANopen axes with `eds`), so that a client reads and writes it as its
    /// type; the drive named as for `sdo`. Nothing is sent to the drive.
    Object {
        /// The axis whose drive it is.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        axis: Option<String>,
        /// Or the drive's position on the bus.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        drive: Option<usize>,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// Load a cam table under `name` (a new name takes a free slot, a known one has its
    /// table replaced; refused while an axis cams on it): from `file` (.csv or .toml, as
    /// the service sees it) or from `points`, exactly one of the two.
    CamLoad {
        /// The table's name.
        name: String,
        /// A cam file the service reads.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        file: Option<String>,
        /// Or the points, `[master, slave]`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        points: Option<Vec<[f64; 2]>>,
        /// `linear`, `cubic` or `quintic` (default: a TOML file's, else cubic).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        interpolation: Option<String>,
        /// Whether the table repeats (default: a TOML file's, else false).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        periodic: Option<bool>,
    },
    /// The cam tables loaded, by slot.
    CamTables,
    /// Quick-stop, disable, take the bus down and end the service.
    Shutdown,
}

impl Request {
    /// The request's `cmd` word.
    pub fn cmd(&self) -> &'static str {
        match self {
            Self::Status => "status",
            Self::Enable { .. } => "enable",
            Self::Disable { .. } => "disable",
            Self::Move { .. } => "move",
            Self::Jog { .. } => "jog",
            Self::Gear { .. } => "gear",
            Self::GearOut { .. } => "gear_out",
            Self::Group { .. } => "group",
            Self::MoveLinear { .. } => "move_linear",
            Self::MoveCircular { .. } => "move_circular",
            Self::Cam { .. } => "cam",
            Self::CamOut { .. } => "cam_out",
            Self::Halt { .. } => "halt",
            Self::Stop { .. } => "stop",
            Self::Release { .. } => "release",
            Self::SetPosition { .. } => "set_position",
            Self::Reset { .. } => "reset",
            Self::Home { .. } => "home",
            Self::Commission { .. } => "commission",
            Self::Procedure { .. } => "procedure",
            Self::DriveHome { .. } => "drive_home",
            Self::Command { .. } => "command",
            Self::Wait { .. } => "wait",
            Self::Trace { .. } => "trace",
            Self::Sdo { .. } => "sdo",
            Self::Object { .. } => "object",
            Self::CamLoad { .. } => "cam_load",
            Self::CamTables => "cam_tables",
            Self::Shutdown => "shutdown",
        }
    }

    /// The axis a one-axis request is for.
    pub fn axis(&self) -> Option<&str> {
        match self {
            Self::Enable { axis }
            | Self::Disable { axis }
            | Self::Move { axis, .. }
            | Self::Jog { axis, .. }
            | Self::Gear { axis, .. }
            | Self::GearOut { axis }
            | Self::Cam { axis, .. }
            | Self::CamOut { axis }
            | Self::Halt { axis }
            | Self::Stop { axis }
            | Self::Release { axis }
            | Self::SetPosition { axis, .. }
            | Self::Home { axis, .. }
            | Self::Commission { axis, .. }
            | Self::DriveHome { axis, .. }
            | Self::Reset { axis } => Some(axis),
            Self::Sdo { axis, .. } | Self::Object { axis, .. } => axis.as_deref(),
            Self::Status
            | Self::Group { .. }
            | Self::MoveLinear { .. }
            | Self::MoveCircular { .. }
            | Self::Procedure { .. }
            | Self::Command { .. }
            | Self::Wait { .. }
            | Self::Trace { .. }
            | Self::CamLoad { .. }
            | Self::CamTables
            | Self::Shutdown => None,
        }
    }

    /// The request as one line of the protocol (without the newline), version included.
    pub fn to_line(&self) -> Result<String, serde_json::Error> {
        serde_json::to_string(&Versioned {
            v: VERSION,
            request: self,
        })
    }
}

/// A request on the wire: the version beside the command's fields.
#[derive(Serialize)]
struct Versioned<'a> {
    v: u64,
    #[serde(flatten)]
    request: &'a Request,
}

/// Why a request line was refused (the reply's `error` is its chain).
#[derive(Debug, Error)]
pub enum ProtocolError {
    /// The line is not JSON.
    #[error("not JSON")]
    NotJson(#[source] serde_json::Error),
    /// The line is JSON but not an object.
    #[error("a request is a JSON object")]
    NotObject,
    /// No `v`.
    #[error("missing \"v\": the protocol version ({VERSION})")]
    NoVersion,
    /// `v` is not a version number.
    #[error("\"v\" is {0}, not a protocol version number (this gantry speaks {VERSION})")]
    BadVersion(Value),
    /// Another version.
    #[error("protocol version {0} is not supported (this gantry speaks {VERSION})")]
    Version(u64),
    /// The command or its fields are wrong.
    #[error("invalid request")]
    Invalid(#[source] serde_json::Error),
}

/// Parses one request line: the version first, then the command.
pub fn parse(line: &str) -> Result<Request, ProtocolError> {
    let mut value: Value = serde_json::from_str(line).map_err(ProtocolError::NotJson)?;
    let obj = value.as_object_mut().ok_or(ProtocolError::NotObject)?;
    match obj.remove("v") {
        None => return Err(ProtocolError::NoVersion),
        Some(v) => match v.as_u64() {
            Some(VERSION) => {}
            Some(other) => return Err(ProtocolError::Version(other)),
            None => return Err(ProtocolError::BadVersion(v)),
        },
    }
    serde_json::from_value(value).map_err(ProtocolError::Invalid)
}

/// A successful reply line.
pub fn ok(result: Value) -> String {
    serde_json::json!({"v": VERSION, "ok": true, "result": result}).to_string()
}

/// An error reply line.
pub fn error(message: &str) -> String {
    serde_json::json!({"v": VERSION, "ok": false, "error": message}).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_chain::Chain;

    /// The reply's error text of a refused line.
    fn refusal(line: &str) -> String {
        Chain(&parse(line).unwrap_err()).to_string()
    }

    /// One request of every kind, with every optional field given.
    fn every_kind() -> Vec<Request> {
        let axis = || "x".to_string();
        vec![
            Request::Status,
            Request::Enable { axis: axis() },
            Request::Disable { axis: axis() },
            Request::Move {
                axis: axis(),
                to: -12.5,
                mode: MoveMode::Negative,
                speed: Some(50.0),
                acceleration: Some(500.0),
                deceleration: Some(400.0),
                jerk: Some(1e4),
                buffer: BufferMode::BlendingPrevious,
            },
            Request::Jog {
                axis: axis(),
                direction: JogDirection::Negative,
                speed: 20.0,
                master: None,
                lock: None,
                lock_position: None,
            },
            Request::Jog {
                axis: axis(),
                direction: JogDirection::Positive,
                speed: 0.5,
                master: Some("m".into()),
                lock: Some(LockDirection::PositionForward),
                lock_position: Some(90.0),
            },
            Request::Gear {
                axis: axis(),
                master: "m".into(),
                numerator: -3,
                denominator: 2,
                source: Some(MasterSource::Actual),
                acceleration: Some(100.0),
                deceleration: None,
                jerk: Some(1e4),
                master_sync_position: Some(90.0),
                slave_sync_position: Some(10.0),
                master_start_distance: Some(45.0),
            },
            Request::GearOut { axis: axis() },
            Request::Cam {
                axis: axis(),
                master: "m".into(),
                table: "knife".into(),
                periodic: Some(false),
                start: Some(CamStartMode::Relative),
                source: None,
                master_offset: Some(1.0),
                slave_offset: Some(-2.0),
                master_scaling: Some(0.5),
                slave_scaling: Some(2.0),
                acceleration: None,
                deceleration: Some(10.0),
                jerk: None,
            },
            Request::CamOut { axis: axis() },
            Request::Group {
                group: "xy".into(),
                op: GroupOp::Enable,
            },
            Request::MoveLinear {
                group: "xy".into(),
                to: vec![10.0, -20.0],
                velocity: 50.0,
                acceleration: Some(500.0),
                deceleration: None,
                jerk: None,
                relative: true,
                buffer: BufferMode::BlendingNext,
                transition: TransitionMode::CornerSuperimposed,
                corner_deviation: Some(0.5),
            },
            Request::MoveCircular {
                group: "xy".into(),
                mode: CircularMode::Radius,
                aux: [-10.0, 0.0],
                end: [20.0, 0.0],
                direction: CircularDirection::Cw,
                axes: Some([1, 0]),
                velocity: 20.0,
                acceleration: None,
                deceleration: Some(100.0),
                jerk: None,
                relative: false,
                buffer: BufferMode::Buffered,
                transition: TransitionMode::None,
                corner_deviation: None,
            },
            Request::Halt { axis: axis() },
            Request::Stop { axis: axis() },
            Request::Release { axis: axis() },
            Request::SetPosition {
                axis: axis(),
                position: 3.25,
            },
            Request::Reset { axis: axis() },
            Request::Command { handle: 7 },
            Request::Wait {
                handle: 7,
                timeout_s: 0.1,
            },
            Request::Trace {
                axes: vec!["x".into(), "y".into()],
                seconds: 2.5,
            },
            Request::Sdo {
                axis: Some(axis()),
                drive: None,
                direction: SdoDirection::Download,
                index: 0x6060,
                sub: 0,
                data: Some("08".into()),
                timeout_s: Some(1.5),
            },
            Request::Object {
                axis: None,
                drive: Some(2),
                index: 0x607A,
                sub: 0,
            },
            Request::Home {
                axis: axis(),
                step_switch: None,
                params: Some(HomeParams {
                    direction: Some(JogDirection::Negative),
                    switches: Some(HomeSwitches::RefAndLimit),
                    mode: Some(HomeMode::Edge2),
                    speed_switch: Some(20.0),
                    max_distance_switch: Some(500.0),
                    speed_reference: Some(2.0),
                    max_distance_reference: Some(10.0),
                    acceleration: Some(200.0),
                    jerk: Some(4000.0),
                    reference_offset: Some(-3.0),
                    normal_position: Some(5.0),
                }),
            },
            Request::Home {
                axis: axis(),
                params: None,
                step_switch: Some(StepSwitchParams {
                    direction: Some(StepDirection::SwitchNegative),
                    switch_mode: Some(StepSwitchMode::FallingEdgeInverse),
                    velocity: Some(20.0),
                    acceleration: Some(200.0),
                    deceleration: Some(40.0),
                    jerk: Some(4000.0),
                    set_position: Some(-7.5),
                    distance_limit: Some(300.0),
                }),
            },
            // The axis' last homing run, with its saved parameters.
            Request::Home {
                axis: axis(),
                params: None,
                step_switch: None,
            },
            Request::Commission {
                axis: axis(),
                procedure: CommissionKind::Reversing,
                from: Some(-5.0),
                to: Some(12.5),
                cycles: Some(3),
                speed: Some(40.0),
                current: None,
            },
            Request::Commission {
                axis: axis(),
                procedure: CommissionKind::Commutation,
                from: None,
                to: None,
                cycles: None,
                speed: None,
                current: Some(250),
            },
            Request::Procedure { id: 4 },
            Request::DriveHome {
                axis: axis(),
                params: DriveHomeParams {
                    method: Some(19),
                    speed_switch: Some(20.0),
                    speed_zero: Some(2.0),
                    acceleration: Some(200.0),
                    home_offset: Some(-1.5),
                    timeout_s: Some(30.0),
                    skip: Some(false),
                },
            },
            Request::CamLoad {
                name: "knife".into(),
                file: None,
                points: Some(vec![[0.0, 0.0], [90.0, 2.5], [180.0, 0.0]]),
                interpolation: Some("quintic".into()),
                periodic: Some(true),
            },
            Request::CamLoad {
                name: "press".into(),
                file: Some("/etc/gantry/cams/press.toml".into()),
                points: None,
                interpolation: None,
                periodic: None,
            },
            Request::CamTables,
            Request::Shutdown,
        ]
    }

    #[test]
    fn every_request_kind_survives_the_wire() {
        let requests = every_kind();
        // Every kind once: a new kind does not compile here until it is numbered, and then
        // fails the count until `every_kind` has it.
        let kind = |r: &Request| match r {
            Request::Status => 0,
            Request::Enable { .. } => 1,
            Request::Disable { .. } => 2,
            Request::Move { .. } => 3,
            Request::Jog { .. } => 4,
            Request::Halt { .. } => 5,
            Request::Stop { .. } => 6,
            Request::Release { .. } => 7,
            Request::SetPosition { .. } => 8,
            Request::Reset { .. } => 9,
            Request::Command { .. } => 10,
            Request::Wait { .. } => 11,
            Request::Trace { .. } => 12,
            Request::Shutdown => 13,
            Request::Sdo { .. } => 14,
            Request::Object { .. } => 15,
            Request::Home { .. } => 16,
            Request::Commission { .. } => 17,
            Request::Procedure { .. } => 18,
            Request::DriveHome { .. } => 19,
            Request::CamLoad { .. } => 20,
            Request::CamTables => 21,
            Request::Gear { .. } => 22,
            Request::GearOut { .. } => 23,
            Request::Cam { .. } => 24,
            Request::CamOut { .. } => 25,
            Request::Group { .. } => 26,
            Request::MoveLinear { .. } => 27,
            Request::MoveCircular { .. } => 28,
        };
        let kinds: std::collections::BTreeSet<usize> = requests.iter().map(kind).collect();
        assert_eq!(kinds, (0..29).collect(), "{requests:?}");
        let words: std::collections::BTreeSet<&str> = requests.iter().map(Request::cmd).collect();
        assert_eq!(words.len(), 29, "{words:?}");
        for r in requests {
            let line = r.to_line().unwrap();
            assert!(!line.contains('\n'), "{line}");
            let value: Value = serde_json::from_str(&line).unwrap();
            assert_eq!(value["v"], VERSION, "{line}");
            assert_eq!(value["cmd"], r.cmd(), "{line}");
            assert_eq!(parse(&line).unwrap(), r, "{line}");
        }
    }

    #[test]
    fn every_word_survives_the_wire() {
        let move_with = |mode, buffer| Request::Move {
            axis: "a".into(),
            to: 1.0,
            mode,
            speed: None,
            acceleration: None,
            deceleration: None,
            jerk: None,
            buffer,
        };
        for &(_, mode) in MoveMode::NAMES {
            for &(_, buffer) in BufferMode::NAMES {
                let r = move_with(mode, buffer);
                assert_eq!(parse(&r.to_line().unwrap()).unwrap(), r);
            }
        }
        for &(word, op) in GroupOp::NAMES {
            let r = Request::Group {
                group: "xy".into(),
                op,
            };
            assert_eq!(parse(&r.to_line().unwrap()).unwrap(), r);
            assert_eq!(word.parse::<GroupOp>().unwrap(), op);
        }
        for &(word, direction) in JogDirection::NAMES {
            let r = Request::Jog {
                axis: "a".into(),
                direction,
                speed: 1.0,
                master: None,
                lock: None,
                lock_position: None,
            };
            assert_eq!(parse(&r.to_line().unwrap()).unwrap(), r);
            // Aliases read as the value they name; it goes out under its canonical word.
            assert_eq!(word.parse::<JogDirection>().unwrap(), direction);
        }
        assert_eq!(JogDirection::Positive.to_string(), "+");
        for &(word, lock) in LockDirection::NAMES {
            assert_eq!(word.parse::<LockDirection>().unwrap(), lock);
        }
        for &(word, source) in MasterSource::NAMES {
            assert_eq!(word.parse::<MasterSource>().unwrap(), source);
        }
        for &(word, start) in CamStartMode::NAMES {
            assert_eq!(word.parse::<CamStartMode>().unwrap(), start);
        }
        assert_eq!(
            "sideways".parse::<LockDirection>().unwrap_err().to_string(),
            "lock \"sideways\" is not one of \"none\", \"immediate-forward\", \
             \"immediate-reverse\", \"position-forward\", \"position-reverse\""
        );
        assert_eq!(BufferMode::BlendingHigh.to_string(), "blending-high");
        // A group move takes the axis move's buffer words, and the transition's.
        for &(_, buffer) in BufferMode::NAMES {
            for &(word, transition) in TransitionMode::NAMES {
                let r = Request::MoveLinear {
                    group: "xy".into(),
                    to: vec![1.0, 2.0],
                    velocity: 10.0,
                    acceleration: None,
                    deceleration: None,
                    jerk: None,
                    relative: false,
                    buffer,
                    transition,
                    corner_deviation: None,
                };
                assert_eq!(parse(&r.to_line().unwrap()).unwrap(), r);
                assert_eq!(word.parse::<TransitionMode>().unwrap(), transition);
            }
        }
        assert_eq!(
            TransitionMode::CornerSuperimposed.to_string(),
            "corner-superimposed"
        );
        for &(word, direction) in StepDirection::NAMES {
            for &(_, switch_mode) in StepSwitchMode::NAMES {
                let r = Request::Home {
                    axis: "a".into(),
                    params: None,
                    step_switch: Some(StepSwitchParams {
                        direction: Some(direction),
                        switch_mode: Some(switch_mode),
                        ..StepSwitchParams::default()
                    }),
                };
                assert_eq!(parse(&r.to_line().unwrap()).unwrap(), r);
            }
            assert_eq!(word.parse::<StepDirection>().unwrap(), direction);
        }
        assert_eq!(StepDirection::SwitchNegative.to_string(), "switch-negative");
        assert_eq!(
            StepSwitchMode::FallingEdgeInverse.to_string(),
            "falling-edge-inverse"
        );
        for &(word, method) in HomeMethod::NAMES {
            assert_eq!(word.parse::<HomeMethod>().unwrap(), method);
            assert_eq!(method.to_string(), word);
        }
    }

    #[test]
    fn a_home_request_names_its_run_or_leaves_it_to_the_axis() {
        let home = |params, step_switch| Request::Home {
            axis: "x".into(),
            params,
            step_switch,
        };
        // What the version-1 CLI sent for `gantry home x`: MoveHome, its saved parameters.
        assert_eq!(
            parse(r#"{"axis":"x","cmd":"home","params":{},"v":1}"#).unwrap(),
            home(Some(HomeParams::default()), None)
        );
        // Neither: the axis' last homing run.
        assert_eq!(
            parse(r#"{"v":1,"cmd":"home","axis":"x"}"#).unwrap(),
            home(None, None)
        );
        assert_eq!(
            parse(r#"{"v":1,"cmd":"home","axis":"x","params":null}"#).unwrap(),
            home(None, None)
        );
        assert_eq!(
            parse(r#"{"v":1,"cmd":"home","axis":"x","step_switch":{"velocity":5}}"#).unwrap(),
            home(
                None,
                Some(StepSwitchParams {
                    velocity: Some(5.0),
                    ..StepSwitchParams::default()
                })
            )
        );
        // A request without a run goes out without either field.
        let line = home(None, None).to_line().unwrap();
        assert!(
            !line.contains("params") && !line.contains("step_switch"),
            "{line}"
        );
        for (line, says) in [
            (
                r#"{"v":1,"cmd":"home","axis":"x","step_switch":{"switch_mode":"edge"}}"#,
                r#"switch_mode "edge" is not one of "on", "off", "rising-edge""#,
            ),
            (
                r#"{"v":1,"cmd":"home","axis":"x","step_switch":{"direction":"up"}}"#,
                r#"direction "up" is not one of "positive", "negative", "switch-positive""#,
            ),
            (
                r#"{"v":1,"cmd":"home","axis":"x","step_switch":{"speed":5}}"#,
                "unknown field `speed`",
            ),
        ] {
            let e = refusal(line);
            assert!(e.contains(says), "{line}\n  said: {e}\n  want: {says}");
        }
    }

    #[test]
    fn what_version_1_clients_sent_still_parses() {
        // The hand-built lines of the version-1 CLI: every field present, null when not
        // given, `v` last.
        let old_move = r#"{"acceleration":null,"axis":"x","buffer":null,"cmd":"move","deceleration":null,"jerk":null,"mode":"relative","speed":100.0,"to":5.0,"v":1}"#;
        assert_eq!(
            parse(old_move).unwrap(),
            Request::Move {
                axis: "x".into(),
                to: 5.0,
                mode: MoveMode::Relative,
                speed: Some(100.0),
                acceleration: None,
                deceleration: None,
                jerk: None,
                buffer: BufferMode::Aborting,
            }
        );
        assert_eq!(
            parse(r#"{"axis":"x","cmd":"jog","direction":"-","speed":20.0,"v":1}"#).unwrap(),
            Request::Jog {
                axis: "x".into(),
                direction: JogDirection::Negative,
                speed: 20.0,
                master: None,
                lock: None,
                lock_position: None,
            }
        );
        // Absent optional fields are their defaults.
        assert_eq!(
            parse(r#"{"v":1,"cmd":"move","axis":"x","to":5}"#).unwrap(),
            Request::Move {
                axis: "x".into(),
                to: 5.0,
                mode: MoveMode::Absolute,
                speed: None,
                acceleration: None,
                deceleration: None,
                jerk: None,
                buffer: BufferMode::Aborting,
            }
        );
        // A group move that says nothing of its junction: aborting, no transition, the
        // group's corner deviation.
        assert_eq!(
            parse(
                r#"{"v":1,"cmd":"move_linear","group":"xy","to":[1,2],"velocity":5,"buffer":null}"#
            )
            .unwrap(),
            Request::MoveLinear {
                group: "xy".into(),
                to: vec![1.0, 2.0],
                velocity: 5.0,
                acceleration: None,
                deceleration: None,
                jerk: None,
                relative: false,
                buffer: BufferMode::Aborting,
                transition: TransitionMode::None,
                corner_deviation: None,
            }
        );
        assert_eq!(parse(r#"{"v":1,"cmd":"status"}"#).unwrap(), Request::Status);
    }

    #[test]
    fn a_wrong_word_is_refused_naming_its_field_and_the_word() {
        for (line, says) in [
            (
                r#"{"v":1,"cmd":"move","axis":"x","to":1,"mode":"sideways"}"#,
                r#"invalid request: mode "sideways" is not one of "absolute", "relative", "shortest", "positive", "negative""#,
            ),
            (
                r#"{"v":1,"cmd":"move","axis":"x","to":1,"buffer":"blended"}"#,
                r#"invalid request: buffer "blended" is not one of "aborting", "buffered", "blending-low", "blending-previous", "blending-next", "blending-high""#,
            ),
            (
                r#"{"v":1,"cmd":"jog","axis":"x","direction":"up","speed":1}"#,
                r#"invalid request: direction "up" is not one of "+", "-", "positive", "negative""#,
            ),
            (
                r#"{"v":1,"cmd":"move_linear","group":"xy","to":[1,2],"velocity":5,"buffer":"blended"}"#,
                r#"invalid request: buffer "blended" is not one of "aborting", "buffered", "blending-low", "blending-previous", "blending-next", "blending-high""#,
            ),
            (
                r#"{"v":1,"cmd":"move_circular","group":"xy","mode":"center","aux":[0,0],"end":[1,1],"velocity":5,"transition":"rounded"}"#,
                r#"invalid request: transition "rounded" is not one of "none", "corner-superimposed""#,
            ),
            // The group moves' old flag is gone: `buffer` says it.
            (
                r#"{"v":1,"cmd":"move_linear","group":"xy","to":[1,2],"velocity":5,"buffered":true}"#,
                "unknown field `buffered`",
            ),
            // Words are exact: no case folding, no padding.
            (
                r#"{"v":1,"cmd":"move","axis":"x","to":1,"mode":"Absolute"}"#,
                r#"mode "Absolute" is not one of"#,
            ),
            (
                r#"{"v":1,"cmd":"jog","axis":"x","direction":" +","speed":1}"#,
                r#"direction " +" is not one of"#,
            ),
            // Not a string: the type is wrong, and the field is named all the same.
            (
                r#"{"v":1,"cmd":"jog","axis":"x","direction":1,"speed":1}"#,
                r#"invalid type: integer `1`, expected direction as one of "+", "-""#,
            ),
            (
                r#"{"v":1,"cmd":"move","axis":"x","to":1,"mode":["relative"]}"#,
                "expected mode as one of",
            ),
            // A jog has no default direction.
            (
                r#"{"v":1,"cmd":"jog","axis":"x","speed":1}"#,
                "missing field `direction`",
            ),
        ] {
            let e = refusal(line);
            assert!(e.contains(says), "{line}\n  said: {e}\n  want: {says}");
        }
        // The command line reads words through the same table and says the same.
        assert_eq!(
            "sideways".parse::<MoveMode>().unwrap_err().to_string(),
            r#"mode "sideways" is not one of "absolute", "relative", "shortest", "positive", "negative""#
        );
    }

    #[test]
    fn mistakes_in_the_line_are_explained() {
        for (line, says) in [
            ("{", "not JSON: EOF while parsing an object"),
            ("[1]", "a JSON object"),
            (r#"{"cmd":"status"}"#, "missing \"v\""),
            (r#"{"v":2,"cmd":"status"}"#, "version 2 is not supported"),
            (
                r#"{"v":"1","cmd":"status"}"#,
                r#""v" is "1", not a protocol version number"#,
            ),
            (
                r#"{"v":1,"cmd":"frob"}"#,
                "invalid request: unknown variant `frob`",
            ),
            (r#"{"v":1,"cmd":"move","axis":"x"}"#, "missing field `to`"),
            (
                r#"{"v":1,"cmd":"move","axis":"x","to":"far"}"#,
                "invalid type",
            ),
            (
                r#"{"v":1,"cmd":"halt","axis":"x","now":true}"#,
                "unknown field `now`",
            ),
        ] {
            let e = refusal(line);
            assert!(e.contains(says), "{line}: {e}");
        }
    }
}
