//! A typed view over one drive's process data, shared by the master (which writes the
//! outputs and reads the inputs) and the simulated drive (which reads the outputs and
//! writes the inputs), so that both sides put every object at the same bytes.
//!
//! In the style of smoltcp's `wire` module: [`OutputImage`] and [`InputImage`] wrap a
//! byte buffer (`&[u8]` to read, `&mut [u8]` to write too) and a [`PdoMap`], the byte
//! offset of every object in a [`PdoLayout`], computed once when the layout is mapped (so
//! that the cyclic path holds no `Vec` and allocates nothing). A view is made only over a
//! buffer that holds the whole mapped direction ([`OutputImage::new_checked`]: a short
//! buffer is an [`ImageError`], not a panic); then every getter of a mapped object has its
//! bytes. A getter of an object the layout does not map gives `None`, a setter does
//! nothing: the mapping, not the view, says what a drive exchanges.
//!
//! Objects are little-endian at the offset the layout's order gives (CiA 301 §7.5.2: a
//! PDO is its mapped objects back to back, in the order of the mapping entries). An object is
//! recognised by index, sub-index and data type; one the view does not know takes its
//! bytes in the image and is not readable through it. Mapped twice, an object is read and
//! written at its first place.

use core::fmt;

use thiserror::Error;

use super::objects::{self, ObjectId};
use super::pdo::PdoLayout;
use super::{Controlword, Statusword};

/// The objects the views know in the outputs (RxPDO, master → drive): what a drive that
/// codes its process data through them can take (the simulated servo's mappable set).
pub const OUTPUT_OBJECTS: [ObjectId; 6] = [
    objects::CONTROLWORD,
    objects::TARGET_POSITION,
    objects::TARGET_VELOCITY,
    objects::TARGET_TORQUE,
    objects::MODES_OF_OPERATION,
    objects::TOUCH_PROBE_FUNCTION,
];
const CONTROLWORD: usize = 0;
const TARGET_POSITION: usize = 1;
const TARGET_VELOCITY: usize = 2;
const TARGET_TORQUE: usize = 3;
const MODES_OF_OPERATION: usize = 4;
const TOUCH_PROBE_FUNCTION: usize = 5;

/// The objects the views know in the inputs (TxPDO, drive → master).
pub const INPUT_OBJECTS: [ObjectId; 13] = [
    objects::STATUSWORD,
    objects::POSITION_ACTUAL_VALUE,
    objects::VELOCITY_ACTUAL_VALUE,
    objects::TORQUE_ACTUAL_VALUE,
    objects::FOLLOWING_ERROR_ACTUAL_VALUE,
    objects::ERROR_CODE,
    objects::MODES_OF_OPERATION_DISPLAY,
    objects::TOUCH_PROBE_STATUS,
    objects::TOUCH_PROBE_POS1_POS_VALUE,
    objects::DIGITAL_INPUTS,
    objects::TOUCH_PROBE_POS1_NEG_VALUE,
    objects::TOUCH_PROBE_POS2_POS_VALUE,
    objects::TOUCH_PROBE_POS2_NEG_VALUE,
];
const STATUSWORD: usize = 0;
const POSITION_ACTUAL_VALUE: usize = 1;
const VELOCITY_ACTUAL_VALUE: usize = 2;
const TORQUE_ACTUAL_VALUE: usize = 3;
const FOLLOWING_ERROR_ACTUAL_VALUE: usize = 4;
const ERROR_CODE: usize = 5;
const MODES_OF_OPERATION_DISPLAY: usize = 6;
const TOUCH_PROBE_STATUS: usize = 7;
const TOUCH_PROBE_POS1_POS_VALUE: usize = 8;
const DIGITAL_INPUTS: usize = 9;
const TOUCH_PROBE_POS1_NEG_VALUE: usize = 10;
const TOUCH_PROBE_POS2_POS_VALUE: usize = 11;
const TOUCH_PROBE_POS2_NEG_VALUE: usize = 12;

/// One direction of the process data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Master → drive (RxPDO, SyncManager 2).
    Outputs,
    /// Drive → master (TxPDO, SyncManager 3).
    Inputs,
}

impl fmt::Display for Direction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Direction::Outputs => "outputs (RxPDO)",
            Direction::Inputs => "inputs (TxPDO)",
        })
    }
}

/// A buffer too short for the mapped process data.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
#[error("process data {direction}: {got} bytes, the PDO layout maps {need}")]
pub struct ImageError {
    /// Which direction.
    pub direction: Direction,
    /// Bytes in the buffer.
    pub got: usize,
    /// Bytes the layout maps.
    pub need: usize,
}

/// Where each object the views know sits in one drive's process data (byte offsets), and
/// the size of each direction: a [`PdoLayout`] resolved once, plain data.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PdoMap {
    /// Bytes of the outputs.
    pub output_bytes: usize,
    /// Bytes of the inputs.
    pub input_bytes: usize,
    outputs: [Option<usize>; OUTPUT_OBJECTS.len()],
    inputs: [Option<usize>; INPUT_OBJECTS.len()],
}

/// The offsets of `known` objects in `mapped` (first place of each), and its size.
fn resolve<const K: usize>(
    mapped: &[ObjectId],
    known: &[ObjectId; K],
) -> ([Option<usize>; K], usize) {
    let mut at = [None; K];
    let mut offset = 0;
    for o in mapped {
        let same = |k: &ObjectId| k.index == o.index && k.sub == o.sub && k.kind == o.kind;
        if let Some(slot) = known.iter().position(same).and_then(|i| at.get_mut(i)) {
            slot.get_or_insert(offset);
        }
        offset += o.kind.size();
    }
    (at, offset)
}

impl PdoMap {
    /// The offsets of the objects in `layout`.
    pub fn of(layout: &PdoLayout) -> Self {
        let (outputs, output_bytes) = resolve(&layout.outputs, &OUTPUT_OBJECTS);
        let (inputs, input_bytes) = resolve(&layout.inputs, &INPUT_OBJECTS);
        Self {
            output_bytes,
            input_bytes,
            outputs,
            inputs,
        }
    }

    /// Byte offset of `object` in the outputs, if mapped and known to the view.
    pub fn output_offset(&self, object: ObjectId) -> Option<usize> {
        offset(&self.outputs, &OUTPUT_OBJECTS, object)
    }

    /// Byte offset of `object` in the inputs, if mapped and known to the view.
    pub fn input_offset(&self, object: ObjectId) -> Option<usize> {
        offset(&self.inputs, &INPUT_OBJECTS, object)
    }
}

fn offset(at: &[Option<usize>], known: &[ObjectId], object: ObjectId) -> Option<usize> {
    let i = known.iter().position(|k| *k == object)?;
    at.get(i).copied().flatten()
}

/// A buffer and the offsets of one direction: what both views are made of.
#[derive(Debug)]
struct Fields<'m, T> {
    buffer: T,
    at: &'m [Option<usize>],
}

impl<'m, T: AsRef<[u8]>> Fields<'m, T> {
    fn new_checked(
        buffer: T,
        at: &'m [Option<usize>],
        direction: Direction,
        need: usize,
    ) -> Result<Self, ImageError> {
        let got = buffer.as_ref().len();
        if got < need {
            return Err(ImageError {
                direction,
                got,
                need,
            });
        }
        Ok(Self { buffer, at })
    }

    /// The `N` bytes of the object in `slot`, if it is mapped.
    fn get<const N: usize>(&self, slot: usize) -> Option<[u8; N]> {
        let at = self.at.get(slot).copied().flatten()?;
        self.buffer
            .as_ref()
            .get(at..at.checked_add(N)?)?
            .try_into()
            .ok()
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Fields<'_, T> {
    /// Writes `value` as the object in `slot`, if it is mapped.
    fn put(&mut self, slot: usize, value: &[u8]) {
        let Some(at) = self.at.get(slot).copied().flatten() else {
            return;
        };
        let Some(end) = at.checked_add(value.len()) else {
            return;
        };
        if let Some(dst) = self.buffer.as_mut().get_mut(at..end) {
            dst.copy_from_slice(value);
        }
    }
}

/// The outputs of one drive (RxPDO: what the master commands).
#[derive(Debug)]
pub struct OutputImage<'m, T>(Fields<'m, T>);

impl<'m, T: AsRef<[u8]>> OutputImage<'m, T> {
    /// A view of `buffer` as the outputs `map` describes; fails when the buffer is
    /// shorter than the mapped outputs (longer is fine: the rest is not looked at).
    pub fn new_checked(buffer: T, map: &'m PdoMap) -> Result<Self, ImageError> {
        Fields::new_checked(buffer, &map.outputs, Direction::Outputs, map.output_bytes).map(Self)
    }

    /// The buffer back.
    pub fn into_inner(self) -> T {
        self.0.buffer
    }

    /// 0x6040 Controlword.
    pub fn controlword(&self) -> Option<Controlword> {
        self.0
            .get(CONTROLWORD)
            .map(u16::from_le_bytes)
            .map(Controlword)
    }

    /// 0x607A Target position (increments).
    pub fn target_position(&self) -> Option<i32> {
        self.0.get(TARGET_POSITION).map(i32::from_le_bytes)
    }

    /// 0x60FF Target velocity (increments/s).
    pub fn target_velocity(&self) -> Option<i32> {
        self.0.get(TARGET_VELOCITY).map(i32::from_le_bytes)
    }

    /// 0x6071 Target torque (per mille of the rated torque).
    pub fn target_torque(&self) -> Option<i16> {
        self.0.get(TARGET_TORQUE).map(i16::from_le_bytes)
    }

    /// 0x6060 Modes of operation (raw: a drive decides which it has).
    pub fn modes_of_operation(&self) -> Option<i8> {
        self.0.get(MODES_OF_OPERATION).map(i8::from_le_bytes)
    }

    /// 0x60B8 Touch probe function.
    pub fn touch_probe_function(&self) -> Option<u16> {
        self.0.get(TOUCH_PROBE_FUNCTION).map(u16::from_le_bytes)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> OutputImage<'_, T> {
    /// Sets 0x6040 Controlword (nothing when not mapped).
    pub fn set_controlword(&mut self, value: Controlword) {
        self.0.put(CONTROLWORD, &value.0.to_le_bytes());
    }

    /// Sets 0x607A Target position (nothing when not mapped).
    pub fn set_target_position(&mut self, value: i32) {
        self.0.put(TARGET_POSITION, &value.to_le_bytes());
    }

    /// Sets 0x60FF Target velocity (nothing when not mapped).
    pub fn set_target_velocity(&mut self, value: i32) {
        self.0.put(TARGET_VELOCITY, &value.to_le_bytes());
    }

    /// Sets 0x6071 Target torque (nothing when not mapped).
    pub fn set_target_torque(&mut self, value: i16) {
        self.0.put(TARGET_TORQUE, &value.to_le_bytes());
    }

    /// Sets 0x6060 Modes of operation (nothing when not mapped).
    pub fn set_modes_of_operation(&mut self, value: i8) {
        self.0.put(MODES_OF_OPERATION, &value.to_le_bytes());
    }

    /// Sets 0x60B8 Touch probe function (nothing when not mapped).
    pub fn set_touch_probe_function(&mut self, value: u16) {
        self.0.put(TOUCH_PROBE_FUNCTION, &value.to_le_bytes());
    }
}

/// The inputs of one drive (TxPDO: what the drive reports).
#[derive(Debug)]
pub struct InputImage<'m, T>(Fields<'m, T>);

impl<'m, T: AsRef<[u8]>> InputImage<'m, T> {
    /// A view of `buffer` as the inputs `map` describes; fails when the buffer is shorter
    /// than the mapped inputs (longer is fine: the rest is not looked at).
    pub fn new_checked(buffer: T, map: &'m PdoMap) -> Result<Self, ImageError> {
        Fields::new_checked(buffer, &map.inputs, Direction::Inputs, map.input_bytes).map(Self)
    }

    /// The buffer back.
    pub fn into_inner(self) -> T {
        self.0.buffer
    }

    /// 0x6041 Statusword.
    pub fn statusword(&self) -> Option<Statusword> {
        self.0
            .get(STATUSWORD)
            .map(u16::from_le_bytes)
            .map(Statusword)
    }

    /// 0x6064 Position actual value (increments; the drive's 32-bit counter).
    pub fn position_actual_value(&self) -> Option<i32> {
        self.0.get(POSITION_ACTUAL_VALUE).map(i32::from_le_bytes)
    }

    /// 0x606C Velocity actual value (increments/s).
    pub fn velocity_actual_value(&self) -> Option<i32> {
        self.0.get(VELOCITY_ACTUAL_VALUE).map(i32::from_le_bytes)
    }

    /// 0x6077 Torque actual value (per mille of the rated torque).
    pub fn torque_actual_value(&self) -> Option<i16> {
        self.0.get(TORQUE_ACTUAL_VALUE).map(i16::from_le_bytes)
    }

    /// 0x60F4 Following error actual value (increments).
    pub fn following_error_actual_value(&self) -> Option<i32> {
        self.0
            .get(FOLLOWING_ERROR_ACTUAL_VALUE)
            .map(i32::from_le_bytes)
    }

    /// 0x603F Error code.
    pub fn error_code(&self) -> Option<u16> {
        self.0.get(ERROR_CODE).map(u16::from_le_bytes)
    }

    /// 0x6061 Modes of operation display (raw).
    pub fn modes_of_operation_display(&self) -> Option<i8> {
        self.0
            .get(MODES_OF_OPERATION_DISPLAY)
            .map(i8::from_le_bytes)
    }

    /// 0x60B9 Touch probe status.
    pub fn touch_probe_status(&self) -> Option<u16> {
        self.0.get(TOUCH_PROBE_STATUS).map(u16::from_le_bytes)
    }

    /// 0x60BA Touch probe position 1 positive value (increments).
    pub fn touch_probe_pos1_pos_value(&self) -> Option<i32> {
        self.0
            .get(TOUCH_PROBE_POS1_POS_VALUE)
            .map(i32::from_le_bytes)
    }

    /// 0x60FD Digital inputs (see [`objects::digital_inputs`]).
    pub fn digital_inputs(&self) -> Option<u32> {
        self.0.get(DIGITAL_INPUTS).map(u32::from_le_bytes)
    }

    /// 0x60BB Touch probe position 1 negative value (increments).
    pub fn touch_probe_pos1_neg_value(&self) -> Option<i32> {
        self.0
            .get(TOUCH_PROBE_POS1_NEG_VALUE)
            .map(i32::from_le_bytes)
    }

    /// 0x60BC Touch probe position 2 positive value (increments).
    pub fn touch_probe_pos2_pos_value(&self) -> Option<i32> {
        self.0
            .get(TOUCH_PROBE_POS2_POS_VALUE)
            .map(i32::from_le_bytes)
    }

    /// 0x60BD Touch probe position 2 negative value (increments).
    pub fn touch_probe_pos2_neg_value(&self) -> Option<i32> {
        self.0
            .get(TOUCH_PROBE_POS2_NEG_VALUE)
            .map(i32::from_le_bytes)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> InputImage<'_, T> {
    /// Sets 0x6041 Statusword (nothing when not mapped).
    pub fn set_statusword(&mut self, value: Statusword) {
        self.0.put(STATUSWORD, &value.0.to_le_bytes());
    }

    /// Sets 0x6064 Position actual value (nothing when not mapped).
    pub fn set_position_actual_value(&mut self, value: i32) {
        self.0.put(POSITION_ACTUAL_VALUE, &value.to_le_bytes());
    }

    /// Sets 0x606C Velocity actual value (nothing when not mapped).
    pub fn set_velocity_actual_value(&mut self, value: i32) {
        self.0.put(VELOCITY_ACTUAL_VALUE, &value.to_le_bytes());
    }

    /// Sets 0x6077 Torque actual value (nothing when not mapped).
    pub fn set_torque_actual_value(&mut self, value: i16) {
        self.0.put(TORQUE_ACTUAL_VALUE, &value.to_le_bytes());
    }

    /// Sets 0x60F4 Following error actual value (nothing when not mapped).
    pub fn set_following_error_actual_value(&mut self, value: i32) {
        self.0
            .put(FOLLOWING_ERROR_ACTUAL_VALUE, &value.to_le_bytes());
    }

    /// Sets 0x603F Error code (nothing when not mapped).
    pub fn set_error_code(&mut self, value: u16) {
        self.0.put(ERROR_CODE, &value.to_le_bytes());
    }

    /// Sets 0x6061 Modes of operation display (nothing when not mapped).
    pub fn set_modes_of_operation_display(&mut self, value: i8) {
        self.0.put(MODES_OF_OPERATION_DISPLAY, &value.to_le_bytes());
    }

    /// Sets 0x60B9 Touch probe status (nothing when not mapped).
    pub fn set_touch_probe_status(&mut self, value: u16) {
        self.0.put(TOUCH_PROBE_STATUS, &value.to_le_bytes());
    }

    /// Sets 0x60BA Touch probe position 1 positive value (nothing when not mapped).
    pub fn set_touch_probe_pos1_pos_value(&mut self, value: i32) {
        self.0.put(TOUCH_PROBE_POS1_POS_VALUE, &value.to_le_bytes());
    }

    /// Sets 0x60FD Digital inputs (nothing when not mapped).
    pub fn set_digital_inputs(&mut self, value: u32) {
        self.0.put(DIGITAL_INPUTS, &value.to_le_bytes());
    }

    /// Sets 0x60BB Touch probe position 1 negative value (nothing when not mapped).
    pub fn set_touch_probe_pos1_neg_value(&mut self, value: i32) {
        self.0.put(TOUCH_PROBE_POS1_NEG_VALUE, &value.to_le_bytes());
    }

    /// Sets 0x60BC Touch probe position 2 positive value (nothing when not mapped).
    pub fn set_touch_probe_pos2_pos_value(&mut self, value: i32) {
        self.0.put(TOUCH_PROBE_POS2_POS_VALUE, &value.to_le_bytes());
    }

    /// Sets 0x60BD Touch probe position 2 negative value (nothing when not mapped).
    pub fn set_touch_probe_pos2_neg_value(&mut self, value: i32) {
        self.0.put(TOUCH_PROBE_POS2_NEG_VALUE, &value.to_le_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia402::objects::DataType;

    /// Every output object, in another order than the view's slots, with an object the
    /// view does not know (0x607C, 4 bytes) in between.
    fn all_outputs() -> PdoLayout {
        PdoLayout {
            outputs: vec![
                objects::MODES_OF_OPERATION,
                objects::CONTROLWORD,
                objects::HOME_OFFSET,
                objects::TARGET_TORQUE,
                objects::TARGET_POSITION,
                objects::TOUCH_PROBE_FUNCTION,
                objects::TARGET_VELOCITY,
            ],
            inputs: vec![],
        }
    }

    fn all_inputs() -> PdoLayout {
        PdoLayout {
            outputs: vec![],
            inputs: vec![
                objects::DIGITAL_INPUTS,
                objects::STATUSWORD,
                objects::MODES_OF_OPERATION_DISPLAY,
                objects::POSITION_ACTUAL_VALUE,
                objects::TORQUE_ACTUAL_VALUE,
                objects::VELOCITY_ACTUAL_VALUE,
                objects::HOME_OFFSET,
                objects::FOLLOWING_ERROR_ACTUAL_VALUE,
                objects::ERROR_CODE,
                objects::TOUCH_PROBE_STATUS,
                objects::TOUCH_PROBE_POS1_POS_VALUE,
            ],
        }
    }

    #[test]
    fn every_output_object_is_written_and_read_at_its_mapped_bytes() {
        let map = PdoMap::of(&all_outputs());
        assert_eq!(map.output_bytes, 1 + 2 + 4 + 2 + 4 + 2 + 4);
        assert_eq!(map.input_bytes, 0);
        let mut buf = [0xEEu8; 19];
        let mut img = OutputImage::new_checked(&mut buf[..], &map).unwrap();
        img.set_modes_of_operation(-3);
        img.set_controlword(Controlword(0x1F0F));
        img.set_target_torque(-1000);
        img.set_target_position(-0x1234_5678);
        img.set_touch_probe_function(0x0015);
        img.set_target_velocity(0x0102_0304);
        #[rustfmt::skip]
        let expect = [
            0xFD,                                   // 0x6060 −3
            0x0F, 0x1F,                             // 0x6040
            0xEE, 0xEE, 0xEE, 0xEE,                 // 0x607C: not the view's, untouched
            0x18, 0xFC,                             // 0x6071 −1000
            0x88, 0xA9, 0xCB, 0xED,                 // 0x607A −0x12345678
            0x15, 0x00,                             // 0x60B8
            0x04, 0x03, 0x02, 0x01,                 // 0x60FF
        ];
        assert_eq!(buf, expect);
        // And read back from bytes written by hand (the drive's side).
        let img = OutputImage::new_checked(&expect[..], &map).unwrap();
        assert_eq!(img.modes_of_operation(), Some(-3));
        assert_eq!(img.controlword(), Some(Controlword(0x1F0F)));
        assert_eq!(img.target_torque(), Some(-1000));
        assert_eq!(img.target_position(), Some(-0x1234_5678));
        assert_eq!(img.touch_probe_function(), Some(0x0015));
        assert_eq!(img.target_velocity(), Some(0x0102_0304));
        assert_eq!(map.output_offset(objects::TARGET_POSITION), Some(9));
        assert_eq!(map.output_offset(objects::HOME_OFFSET), None);
    }

    #[test]
    fn every_input_object_is_written_and_read_at_its_mapped_bytes() {
        let map = PdoMap::of(&all_inputs());
        assert_eq!(map.input_bytes, 4 + 2 + 1 + 4 + 2 + 4 + 4 + 4 + 2 + 2 + 4);
        let mut buf = [0xEEu8; 33];
        let mut img = InputImage::new_checked(&mut buf[..], &map).unwrap();
        img.set_digital_inputs(objects::digital_inputs::HOME_SWITCH | 0x8000_0000);
        img.set_statusword(Statusword(0x1637));
        img.set_modes_of_operation_display(8);
        img.set_position_actual_value(i32::MIN + 1);
        img.set_torque_actual_value(-2);
        img.set_velocity_actual_value(-100_000);
        img.set_following_error_actual_value(7);
        img.set_error_code(0x8611);
        img.set_touch_probe_status(0x0003);
        img.set_touch_probe_pos1_pos_value(0x7FFF_FFFF);
        #[rustfmt::skip]
        let expect = [
            0x04, 0x00, 0x00, 0x80,                 // 0x60FD
            0x37, 0x16,                             // 0x6041
            0x08,                                   // 0x6061
            0x01, 0x00, 0x00, 0x80,                 // 0x6064 −2³¹ + 1
            0xFE, 0xFF,                             // 0x6077 −2
            0x60, 0x79, 0xFE, 0xFF,                 // 0x606C −100 000
            0xEE, 0xEE, 0xEE, 0xEE,                 // 0x607C: not the view's, untouched
            0x07, 0x00, 0x00, 0x00,                 // 0x60F4
            0x11, 0x86,                             // 0x603F
            0x03, 0x00,                             // 0x60B9
            0xFF, 0xFF, 0xFF, 0x7F,                 // 0x60BA
        ];
        assert_eq!(buf, expect);
        let img = InputImage::new_checked(&expect[..], &map).unwrap();
        assert_eq!(img.digital_inputs(), Some(0x8000_0004));
        assert_eq!(img.statusword(), Some(Statusword(0x1637)));
        assert_eq!(img.modes_of_operation_display(), Some(8));
        assert_eq!(img.position_actual_value(), Some(i32::MIN + 1));
        assert_eq!(img.torque_actual_value(), Some(-2));
        assert_eq!(img.velocity_actual_value(), Some(-100_000));
        assert_eq!(img.following_error_actual_value(), Some(7));
        assert_eq!(img.error_code(), Some(0x8611));
        assert_eq!(img.touch_probe_status(), Some(3));
        assert_eq!(img.touch_probe_pos1_pos_value(), Some(i32::MAX));
        assert_eq!(map.input_offset(objects::ERROR_CODE), Some(25));
    }

    #[test]
    fn objects_not_mapped_read_none_and_are_not_written() {
        let map = PdoMap::of(&PdoLayout::csp_minimal());
        let mut out = [0xAAu8; 8];
        let mut img = OutputImage::new_checked(&mut out[..], &map).unwrap();
        img.set_target_velocity(5);
        img.set_target_torque(5);
        img.set_modes_of_operation(8);
        img.set_touch_probe_function(1);
        assert_eq!(img.target_velocity(), None);
        assert_eq!(img.modes_of_operation(), None);
        assert_eq!(img.touch_probe_function(), None);
        assert_eq!(out, [0xAA; 8], "nothing written");
        let mut inp = [0xAAu8; 6];
        let mut img = InputImage::new_checked(&mut inp[..], &map).unwrap();
        img.set_error_code(1);
        img.set_velocity_actual_value(1);
        img.set_digital_inputs(1);
        assert_eq!(img.error_code(), None);
        assert_eq!(img.following_error_actual_value(), None);
        assert_eq!(img.statusword(), Some(Statusword(0xAAAA)));
        assert_eq!(inp, [0xAA; 6], "nothing written");
    }

    #[test]
    fn short_buffers_are_an_error_naming_the_direction_and_sizes() {
        let map = PdoMap::of(&PdoLayout::csp());
        assert_eq!((map.output_bytes, map.input_bytes), (7, 15));
        for n in 0..7 {
            let mut b = vec![0u8; n];
            let e = OutputImage::new_checked(&mut b[..], &map).unwrap_err();
            assert_eq!(
                e,
                ImageError {
                    direction: Direction::Outputs,
                    got: n,
                    need: 7
                }
            );
        }
        for n in 0..15 {
            let b = vec![0u8; n];
            let e = InputImage::new_checked(&b[..], &map).unwrap_err();
            assert_eq!((e.direction, e.got, e.need), (Direction::Inputs, n, 15));
        }
        assert_eq!(
            InputImage::new_checked(&[0u8; 3][..], &map)
                .unwrap_err()
                .to_string(),
            "process data inputs (TxPDO): 3 bytes, the PDO layout maps 15"
        );
        // A longer buffer is fine; the view reads only the mapped bytes.
        assert!(InputImage::new_checked(&[0u8; 64][..], &map).is_ok());
        // An empty layout needs no bytes.
        let none = PdoMap::default();
        assert!(OutputImage::new_checked(&[][..], &none).is_ok());
    }

    #[test]
    fn an_object_of_another_type_or_mapped_twice_is_taken_by_the_rules() {
        // 0x607A as 16 bits is not the CiA 402 target position: not read as one, but its
        // two bytes are in the image.
        let narrow = ObjectId {
            kind: DataType::I16,
            ..objects::TARGET_POSITION
        };
        let map = PdoMap::of(&PdoLayout {
            outputs: vec![narrow, objects::CONTROLWORD, objects::CONTROLWORD],
            inputs: vec![],
        });
        assert_eq!(map.output_bytes, 6);
        assert_eq!(map.output_offset(objects::TARGET_POSITION), None);
        assert_eq!(
            map.output_offset(objects::CONTROLWORD),
            Some(2),
            "first place"
        );
        let mut b = [0u8; 6];
        let mut img = OutputImage::new_checked(&mut b[..], &map).unwrap();
        img.set_controlword(Controlword(0x0F));
        img.set_target_position(-1);
        assert_eq!(img.into_inner(), &[0, 0, 0x0F, 0, 0, 0]);
    }

    #[test]
    fn the_map_agrees_with_the_layout_offsets() {
        for layout in [PdoLayout::csp(), PdoLayout::csp_minimal()] {
            let map = PdoMap::of(&layout);
            assert_eq!(map.output_bytes, layout.output_bytes());
            assert_eq!(map.input_bytes, layout.input_bytes());
            for o in &layout.outputs {
                assert_eq!(
                    map.output_offset(*o),
                    layout.output_offset(o.index),
                    "{o:?}"
                );
            }
            for o in &layout.inputs {
                if INPUT_OBJECTS.contains(o) {
                    assert_eq!(map.input_offset(*o), layout.input_offset(o.index), "{o:?}");
                }
            }
        }
    }
}
