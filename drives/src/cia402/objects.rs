//! Object dictionary entries of CiA 402-2 used by gantry, with the standard's names.

/// An object dictionary entry: index, sub-index and the data type on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ObjectId {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Data type.
    pub kind: DataType,
    /// The standard's name.
    pub name: &'static str,
}

/// Data types of the objects below (CiA 301 §7.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DataType {
    /// INTEGER8.
    I8,
    /// UNSIGNED8.
    U8,
    /// INTEGER16.
    I16,
    /// UNSIGNED16.
    U16,
    /// INTEGER32.
    I32,
    /// UNSIGNED32.
    U32,
}

impl DataType {
    /// Size on the wire (bytes).
    pub const fn size(self) -> usize {
        match self {
            DataType::I8 | DataType::U8 => 1,
            DataType::I16 | DataType::U16 => 2,
            DataType::I32 | DataType::U32 => 4,
        }
    }
}

const fn obj(index: u16, sub: u8, kind: DataType, name: &'static str) -> ObjectId {
    ObjectId {
        index,
        sub,
        kind,
        name,
    }
}

/// 0x603F Error code (last drive error, CiA 402 Table 9 codes).
pub const ERROR_CODE: ObjectId = obj(0x603F, 0, DataType::U16, "Error code");
/// 0x6040 Controlword.
pub const CONTROLWORD: ObjectId = obj(0x6040, 0, DataType::U16, "Controlword");
/// 0x6041 Statusword.
pub const STATUSWORD: ObjectId = obj(0x6041, 0, DataType::U16, "Statusword");
/// 0x605A Quick stop option code.
pub const QUICK_STOP_OPTION_CODE: ObjectId =
    obj(0x605A, 0, DataType::I16, "Quick stop option code");
/// 0x605B Shutdown option code (transition 8: 0 disable drive function, 1 slow down
/// on the slow down ramp, then disable).
pub const SHUTDOWN_OPTION_CODE: ObjectId = obj(0x605B, 0, DataType::I16, "Shutdown option code");
/// 0x605C Disable operation option code (transition 5: as 0x605B).
pub const DISABLE_OPERATION_OPTION_CODE: ObjectId =
    obj(0x605C, 0, DataType::I16, "Disable operation option code");
/// 0x605E Fault reaction option code (0 disable drive function, 1 slow down ramp, 2 quick
/// stop ramp, 3 current limit, 4 voltage limit).
pub const FAULT_REACTION_OPTION_CODE: ObjectId =
    obj(0x605E, 0, DataType::I16, "Fault reaction option code");
/// 0x6060 Modes of operation.
pub const MODES_OF_OPERATION: ObjectId = obj(0x6060, 0, DataType::I8, "Modes of operation");
/// 0x6061 Modes of operation display.
pub const MODES_OF_OPERATION_DISPLAY: ObjectId =
    obj(0x6061, 0, DataType::I8, "Modes of operation display");
/// 0x6064 Position actual value (increments).
pub const POSITION_ACTUAL_VALUE: ObjectId = obj(0x6064, 0, DataType::I32, "Position actual value");
/// 0x6065 Following error window (increments).
pub const FOLLOWING_ERROR_WINDOW: ObjectId =
    obj(0x6065, 0, DataType::U32, "Following error window");
/// 0x6066 Following error time out (ms).
pub const FOLLOWING_ERROR_TIME_OUT: ObjectId =
    obj(0x6066, 0, DataType::U16, "Following error time out");
/// 0x606C Velocity actual value (increments/s).
pub const VELOCITY_ACTUAL_VALUE: ObjectId = obj(0x606C, 0, DataType::I32, "Velocity actual value");
/// 0x6071 Target torque (per mille of rated torque).
pub const TARGET_TORQUE: ObjectId = obj(0x6071, 0, DataType::I16, "Target torque");
/// 0x6072 Max torque (per mille of rated torque).
pub const MAX_TORQUE: ObjectId = obj(0x6072, 0, DataType::U16, "Max torque");
/// 0x6076 Motor rated torque (mN·m): the unit of the torque objects.
pub const MOTOR_RATED_TORQUE: ObjectId = obj(0x6076, 0, DataType::U32, "Motor rated torque");
/// 0x6077 Torque actual value (per mille of rated torque).
pub const TORQUE_ACTUAL_VALUE: ObjectId = obj(0x6077, 0, DataType::I16, "Torque actual value");
/// 0x607A Target position (increments).
pub const TARGET_POSITION: ObjectId = obj(0x607A, 0, DataType::I32, "Target position");
/// 0x607C Home offset (increments).
pub const HOME_OFFSET: ObjectId = obj(0x607C, 0, DataType::I32, "Home offset");
/// 0x607F Max profile velocity (increments/s).
pub const MAX_PROFILE_VELOCITY: ObjectId = obj(0x607F, 0, DataType::U32, "Max profile velocity");
/// 0x6084 Profile deceleration (increments/s²): the "slow down ramp" of the option codes.
pub const PROFILE_DECELERATION: ObjectId = obj(0x6084, 0, DataType::U32, "Profile deceleration");
/// 0x6085 Quick stop deceleration (increments/s²).
pub const QUICK_STOP_DECELERATION: ObjectId =
    obj(0x6085, 0, DataType::U32, "Quick stop deceleration");
/// 0x6098 Homing method.
pub const HOMING_METHOD: ObjectId = obj(0x6098, 0, DataType::I8, "Homing method");
/// 0x6099:1 Homing speeds — speed during search for switch.
pub const HOMING_SPEED_SWITCH: ObjectId =
    obj(0x6099, 1, DataType::U32, "Speed during search for switch");
/// 0x6099:2 Homing speeds — speed during search for zero.
pub const HOMING_SPEED_ZERO: ObjectId =
    obj(0x6099, 2, DataType::U32, "Speed during search for zero");
/// 0x609A Homing acceleration.
pub const HOMING_ACCELERATION: ObjectId = obj(0x609A, 0, DataType::U32, "Homing acceleration");
/// 0x60B8 Touch probe function.
pub const TOUCH_PROBE_FUNCTION: ObjectId = obj(0x60B8, 0, DataType::U16, "Touch probe function");
/// 0x60B9 Touch probe status.
pub const TOUCH_PROBE_STATUS: ObjectId = obj(0x60B9, 0, DataType::U16, "Touch probe status");
/// 0x60BA Touch probe position 1 positive value.
pub const TOUCH_PROBE_POS1_POS_VALUE: ObjectId = obj(
    0x60BA,
    0,
    DataType::I32,
    "Touch probe position 1 positive value",
);
/// 0x60BB Touch probe position 1 negative value.
pub const TOUCH_PROBE_POS1_NEG_VALUE: ObjectId = obj(
    0x60BB,
    0,
    DataType::I32,
    "Touch probe position 1 negative value",
);
/// 0x60BC Touch probe position 2 positive value.
pub const TOUCH_PROBE_POS2_POS_VALUE: ObjectId = obj(
    0x60BC,
    0,
    DataType::I32,
    "Touch probe position 2 positive value",
);
/// 0x60BD Touch probe position 2 negative value.
pub const TOUCH_PROBE_POS2_NEG_VALUE: ObjectId = obj(
    0x60BD,
    0,
    DataType::I32,
    "Touch probe position 2 negative value",
);
/// 0x60D0:1 Touch probe source of probe 1 (ETG.6010; used when 0x60B8 bits 2–3 = 10b).
pub const TOUCH_PROBE_1_SOURCE: ObjectId = obj(0x60D0, 1, DataType::I16, "Touch probe 1 source");
/// 0x60D0:2 Touch probe source of probe 2 (ETG.6010; used when 0x60B8 bits 10–11 = 10b).
pub const TOUCH_PROBE_2_SOURCE: ObjectId = obj(0x60D0, 2, DataType::I16, "Touch probe 2 source");

/// Values of 0x60D0 (ETG.6010, as drives implementing it list them): 1–4 the touch probe
/// inputs, 5 the encoder's hardware zero impulse, 6 a software zero impulse; 0 reserved;
/// negative values manufacturer-specific (a drive's own inputs, e.g. its limit switches).
pub mod touch_probe_source {
    /// Touch probe input 1.
    pub const PROBE_INPUT_1: i16 = 1;
    /// Touch probe input 2.
    pub const PROBE_INPUT_2: i16 = 2;
    /// Touch probe input 3.
    pub const PROBE_INPUT_3: i16 = 3;
    /// Touch probe input 4.
    pub const PROBE_INPUT_4: i16 = 4;
    /// Hardware zero impulse signal of the position encoder.
    pub const HARDWARE_ZERO_IMPULSE: i16 = 5;
    /// Software zero impulse signal of the position encoder.
    pub const SOFTWARE_ZERO_IMPULSE: i16 = 6;
}

/// 0x60F4 Following error actual value.
pub const FOLLOWING_ERROR_ACTUAL_VALUE: ObjectId =
    obj(0x60F4, 0, DataType::I32, "Following error actual value");
/// 0x60FD Digital inputs (bit 0 negative limit, 1 positive limit, 2 home switch).
pub const DIGITAL_INPUTS: ObjectId = obj(0x60FD, 0, DataType::U32, "Digital inputs");
/// 0x60FF Target velocity (increments/s).
pub const TARGET_VELOCITY: ObjectId = obj(0x60FF, 0, DataType::I32, "Target velocity");

/// Every object above, for tables and lookups.
pub const ALL: [ObjectId; 37] = [
    ERROR_CODE,
    CONTROLWORD,
    STATUSWORD,
    QUICK_STOP_OPTION_CODE,
    SHUTDOWN_OPTION_CODE,
    DISABLE_OPERATION_OPTION_CODE,
    FAULT_REACTION_OPTION_CODE,
    MODES_OF_OPERATION,
    MODES_OF_OPERATION_DISPLAY,
    POSITION_ACTUAL_VALUE,
    FOLLOWING_ERROR_WINDOW,
    FOLLOWING_ERROR_TIME_OUT,
    VELOCITY_ACTUAL_VALUE,
    TARGET_TORQUE,
    MAX_TORQUE,
    MOTOR_RATED_TORQUE,
    TORQUE_ACTUAL_VALUE,
    TARGET_POSITION,
    HOME_OFFSET,
    MAX_PROFILE_VELOCITY,
    PROFILE_DECELERATION,
    QUICK_STOP_DECELERATION,
    HOMING_METHOD,
    HOMING_SPEED_SWITCH,
    HOMING_SPEED_ZERO,
    HOMING_ACCELERATION,
    TOUCH_PROBE_FUNCTION,
    TOUCH_PROBE_STATUS,
    TOUCH_PROBE_POS1_POS_VALUE,
    TOUCH_PROBE_POS1_NEG_VALUE,
    TOUCH_PROBE_POS2_POS_VALUE,
    TOUCH_PROBE_POS2_NEG_VALUE,
    TOUCH_PROBE_1_SOURCE,
    TOUCH_PROBE_2_SOURCE,
    FOLLOWING_ERROR_ACTUAL_VALUE,
    DIGITAL_INPUTS,
    TARGET_VELOCITY,
];

/// The object at `index:sub`, if gantry knows it.
pub fn lookup(index: u16, sub: u8) -> Option<ObjectId> {
    ALL.iter()
        .copied()
        .find(|o| o.index == index && o.sub == sub)
}

/// Bits of 0x60FD Digital inputs (CiA 402-2 §8.4.8).
pub mod digital_inputs {
    /// Negative limit switch.
    pub const NEGATIVE_LIMIT: u32 = 1 << 0;
    /// Positive limit switch.
    pub const POSITIVE_LIMIT: u32 = 1 << 1;
    /// Home switch.
    pub const HOME_SWITCH: u32 = 1 << 2;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn objects_are_unique() {
        for (i, a) in ALL.iter().enumerate() {
            for b in ALL.iter().skip(i + 1) {
                assert!(!(a.index == b.index && a.sub == b.sub), "{a:?} twice");
            }
        }
    }

    #[test]
    fn lookup_finds_objects_and_sizes_match_types() {
        assert_eq!(lookup(0x6041, 0), Some(STATUSWORD));
        assert_eq!(lookup(0x6099, 2), Some(HOMING_SPEED_ZERO));
        assert_eq!(lookup(0x1234, 0), None);
        assert_eq!(TARGET_POSITION.kind.size(), 4);
        assert_eq!(CONTROLWORD.kind.size(), 2);
        assert_eq!(MODES_OF_OPERATION.kind.size(), 1);
    }
}
