//! Process data objects (CiA 301 §7.2.2, §7.5.2.35–.38): [`DEFAULT_PDO_COUNT`] receive and
//! transmit PDOs by default, up to [`MAX_PDO_COUNT`] each way (a node's `pdo_count`), each
//! a communication parameter record (0x1400+n / 0x1800+n) and a mapping record (0x1600+n /
//! 0x1A00+n), with the rules a CiA 301 device enforces on the SDO writes that configure
//! them:
//!
//! - **COB-ID** (sub 1): bit 31 set = PDO does not exist (invalid). Bits 0–29 may not
//!   change while the PDO exists (§7.5.2.35: "it is not allowed to change bit 0 to 29
//!   while the PDO exists"), abort 0x06090030; 29-bit identifiers (bit 29) are not
//!   supported, abort 0x06090030; a PDO is made valid only on an identifier that is not
//!   one of CiA 301's restricted CAN-IDs ([`restricted`]: 0 among them), abort
//!   0x06090030. PDOs 1–4 power up on their predefined identifiers (Table 75);
//!   PDOs 5 and up have none (the predefined connection set stops at four): they power
//!   up invalid with identifier 0 (0x80000000, as CANopenNode's dictionaries have them),
//!   and the master gives them one.
//! - **Transmission type** (sub 2): RPDO 0–240 synchronous (the data takes effect at the
//!   next SYNC), 254/255 event-driven (at once); TPDO 0 synchronous acyclic, 1–240 every
//!   n-th SYNC, 254/255 event-driven; 241–251 are reserved and 252/253 (RTR only) not
//!   supported: abort 0x06090030.
//! - **Inhibit time** (TPDO sub 3, 100 µs) and **SYNC start value** (TPDO sub 6,
//!   0..=240) may not change while the PDO exists (§7.5.2.36), abort 0x06090030; **event
//!   timer** (sub 5, ms) may: a TPDO's period without change, an RPDO's deadline
//!   (§7.5.2.35: no RPDO within it after the last is an RPDO timeout). With a start value and SYNCs carrying a counter, a
//!   cyclic TPDO is first sent at the SYNC whose counter equals it (spreading the TPDOs
//!   of several nodes over the cycles).
//! - **Mapping** (§7.5.2.37 procedure: invalidate the PDO, set sub 0 to 0, write the
//!   entries, set sub 0 to their number, validate): any write while the PDO exists is
//!   refused with 0x08000022; an entry written while sub 0 is not 0 with 0x08000022; an
//!   entry naming an object that does not exist, is not mappable in this direction or has
//!   another bit length with 0x06040041; a count whose entries exceed 64 bits with
//!   0x06040042, more than [`MAX_MAPPED`] entries or an empty entry below it with
//!   0x06040041 / 0x06090031.
//!
//! Mappable objects are those the device codes its process data through
//! (its [`DeviceKind::outputs`] into RPDOs, its [`DeviceKind::inputs`] into TPDOs), whole
//! objects only (bit lengths are multiples of 8), and in RPDOs the dummy entries
//! ([`DUMMIES`]).

use super::device::DeviceKind;
use gantry_drives::canopen::sdo::AbortCode;
use gantry_drives::cia402::objects::{DataType, ObjectId};
use gantry_drives::cia402::pdo::parse_mapping_entry;

/// First RPDO communication parameter (CiA 301 §7.5.2.35).
pub const RPDO_COMMUNICATION: u16 = 0x1400;
/// First RPDO mapping parameter (§7.5.2.37).
pub const RPDO_MAPPING: u16 = 0x1600;
/// First TPDO communication parameter (§7.5.2.36).
pub const TPDO_COMMUNICATION: u16 = 0x1800;
/// First TPDO mapping parameter (§7.5.2.38).
pub const TPDO_MAPPING: u16 = 0x1A00;
/// PDOs per direction a node has unless its configuration says otherwise: the predefined
/// connection set's four (CiA 301 Table 75), what most CiA 402 drives offer.
pub const DEFAULT_PDO_COUNT: u8 = 4;
/// Most PDOs per direction a simulated node may have (CiA 301 allows 512: eight are
/// enough for any CiA 402 layout and keep the node's arrays small).
pub const MAX_PDO_COUNT: usize = 8;
/// Most entries of one mapping (one byte each at least: 8 fill a CAN frame).
pub const MAX_MAPPED: usize = 8;
/// Bits a PDO carries at most (8 data bytes).
pub const MAX_PDO_BITS: u32 = 64;
/// COB-ID bit 31: the PDO does not exist (invalid).
pub const COB_ID_INVALID: u32 = 1 << 31;
/// COB-ID bit 30: TPDO, no RTR allowed on it (this node never answers RTRs).
pub const COB_ID_NO_RTR: u32 = 1 << 30;
/// COB-ID bit 29: 29-bit identifier (not supported: classical 11-bit CAN only).
pub const COB_ID_EXTENDED: u32 = 1 << 29;
/// Transmission type: synchronous acyclic (TPDO: at SYNC when changed; RPDO: at SYNC).
pub const TT_SYNC_ACYCLIC: u8 = 0;
/// Highest synchronous cyclic transmission type (every 240th SYNC).
pub const TT_SYNC_MAX: u8 = 240;
/// Event-driven, manufacturer-specific.
pub const TT_EVENT_MANUFACTURER: u8 = 254;
/// Event-driven, device profile (CiA 402: on change of a mapped value).
pub const TT_EVENT_PROFILE: u8 = 255;

/// Which way a PDO goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Receive PDO: master → node.
    Receive,
    /// Transmit PDO: node → master.
    Transmit,
}

impl Direction {
    /// The objects that may be mapped this way in a PDO of a `kind` device.
    pub const fn mappable(self, kind: DeviceKind) -> &'static [ObjectId] {
        match self {
            Self::Receive => kind.outputs(),
            Self::Transmit => kind.inputs(),
        }
    }

    /// Highest sub-index of the communication record (RPDO: COB-ID, type, event timer;
    /// TPDO: also inhibit time, SYNC start value; sub 4 is reserved, RPDO sub 3 unused).
    pub const fn comm_subs(self) -> u8 {
        match self {
            Self::Receive => 5,
            Self::Transmit => 6,
        }
    }
}

/// When a PDO goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Trigger {
    /// At SYNC: an RPDO's data takes effect at the next SYNC; a TPDO is sent at every
    /// n-th SYNC (`0`: acyclic, at SYNC when a value changed).
    Sync(u8),
    /// On an event: an RPDO takes effect at once; a TPDO is sent when a mapped value
    /// changed (no sooner than the inhibit time) and at least every event-timer period.
    Event,
}

/// One PDO's parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Pdo {
    /// The device whose objects it maps.
    pub kind: DeviceKind,
    /// Which way.
    pub direction: Direction,
    /// Sub 1: COB-ID with the valid bit.
    pub cob_id: u32,
    /// Sub 2: transmission type.
    pub transmission_type: u8,
    /// TPDO sub 3: inhibit time (100 µs).
    pub inhibit_time: u16,
    /// Sub 5: event timer (ms, 0 = off): TPDO period, RPDO deadline.
    pub event_timer_ms: u16,
    /// TPDO sub 6: SYNC start value (0 = not used).
    pub sync_start: u8,
    /// Mapping sub 0: number of entries in use.
    pub count: u8,
    /// Mapping subs 1..=8: index << 16 | sub << 8 | bit length.
    pub entries: [u32; MAX_MAPPED],
}

impl Pdo {
    /// An invalid PDO of a `kind` device on `cob_id` (its predefined identifier) with
    /// no mapping.
    pub const fn unused(kind: DeviceKind, direction: Direction, cob_id: u16) -> Self {
        Self {
            kind,
            direction,
            cob_id: COB_ID_INVALID | cob_id as u32,
            transmission_type: TT_EVENT_PROFILE,
            inhibit_time: 0,
            event_timer_ms: 0,
            sync_start: 0,
            count: 0,
            entries: [0; MAX_MAPPED],
        }
    }

    /// A valid synchronous PDO (every SYNC) on `cob_id` mapping `objects` (at most 8).
    pub fn synchronous(
        kind: DeviceKind,
        direction: Direction,
        cob_id: u16,
        objects: &[ObjectId],
    ) -> Self {
        let mut p = Self::unused(kind, direction, cob_id);
        p.cob_id = u32::from(cob_id);
        p.transmission_type = 1;
        for (e, o) in p.entries.iter_mut().zip(objects) {
            *e = gantry_drives::cia402::pdo::mapping_entry(o);
        }
        p.count = objects.len().min(MAX_MAPPED) as u8;
        p
    }

    /// Whether the PDO exists (COB-ID bit 31 clear).
    pub const fn is_valid(&self) -> bool {
        self.cob_id & COB_ID_INVALID == 0
    }

    /// The 11-bit CAN identifier.
    pub const fn can_id(&self) -> u16 {
        (self.cob_id & 0x7FF) as u16
    }

    /// When it goes.
    pub const fn trigger(&self) -> Trigger {
        match self.transmission_type {
            TT_EVENT_MANUFACTURER | TT_EVENT_PROFILE => Trigger::Event,
            n => Trigger::Sync(n),
        }
    }

    /// The mapped objects, in order (entries 1..=count).
    pub fn mapped(&self) -> impl Iterator<Item = ObjectId> + '_ {
        let n = usize::from(self.count).min(MAX_MAPPED);
        let (kind, dir) = (self.kind, self.direction);
        self.entries
            .iter()
            .take(n)
            .filter_map(move |e| mappable(kind, dir, *e).ok())
    }

    /// Data bytes of the PDO.
    pub fn len(&self) -> usize {
        self.mapped().map(|o| o.kind.size()).sum()
    }

    /// Whether it maps nothing.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// SDO read of the communication record, sub `sub` (little-endian into `out`).
    pub fn read_comm(&self, sub: u8, out: &mut [u8]) -> Result<usize, AbortCode> {
        match (sub, self.direction) {
            (0, d) => put(out, &[d.comm_subs()]),
            (1, _) => put(out, &self.cob_id.to_le_bytes()),
            (2, _) => put(out, &[self.transmission_type]),
            (3, Direction::Transmit) => put(out, &self.inhibit_time.to_le_bytes()),
            (5, _) => put(out, &self.event_timer_ms.to_le_bytes()),
            (6, Direction::Transmit) => put(out, &[self.sync_start]),
            _ => Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST),
        }
    }

    /// Size of communication sub `sub`, and whether it is writable.
    pub fn comm_entry(&self, sub: u8) -> Result<(usize, bool), AbortCode> {
        match (sub, self.direction) {
            (0, _) => Ok((1, false)),
            (1, _) => Ok((4, true)),
            (2, _) => Ok((1, true)),
            (3, Direction::Transmit) | (5, _) => Ok((2, true)),
            (6, Direction::Transmit) => Ok((1, true)),
            _ => Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST),
        }
    }

    /// SDO write of the communication record (length already checked).
    pub fn write_comm(&mut self, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        match sub {
            1 => {
                let v = u32::from_le_bytes(four(data));
                if v & COB_ID_EXTENDED != 0 || (v & 0x1FFF_F800) != 0 {
                    // 29-bit identifiers are not supported (CAN 2.0A only).
                    return Err(AbortCode::INVALID_VALUE);
                }
                // Bits 0–29 may change only while the PDO does not exist.
                let id_bits = !(COB_ID_INVALID | COB_ID_NO_RTR);
                let new_valid = v & COB_ID_INVALID == 0;
                if self.is_valid() && new_valid && (v & id_bits) != (self.cob_id & id_bits) {
                    return Err(AbortCode::INVALID_VALUE);
                }
                if new_valid && !self.is_valid() && restricted((v & 0x7FF) as u16) {
                    return Err(AbortCode::INVALID_VALUE);
                }
                self.cob_id = v;
                Ok(())
            }
            2 => {
                let t = data.first().copied().unwrap_or(0);
                // Both directions: 0..=240 and 254/255 (241–251 reserved; 252/253 are
                // RTR-only TPDOs, which this node does not answer).
                if !(t <= TT_SYNC_MAX || t >= TT_EVENT_MANUFACTURER) {
                    return Err(AbortCode::INVALID_VALUE);
                }
                self.transmission_type = t;
                Ok(())
            }
            3 if self.direction == Direction::Transmit => {
                if self.is_valid() {
                    return Err(AbortCode::INVALID_VALUE);
                }
                self.inhibit_time = u16::from_le_bytes([
                    data.first().copied().unwrap_or(0),
                    data.get(1).copied().unwrap_or(0),
                ]);
                Ok(())
            }
            5 => {
                self.event_timer_ms = u16::from_le_bytes([
                    data.first().copied().unwrap_or(0),
                    data.get(1).copied().unwrap_or(0),
                ]);
                Ok(())
            }
            6 if self.direction == Direction::Transmit => {
                let v = data.first().copied().unwrap_or(0);
                if self.is_valid() || v > TT_SYNC_MAX {
                    return Err(AbortCode::INVALID_VALUE);
                }
                self.sync_start = v;
                Ok(())
            }
            0 => Err(AbortCode::READ_ONLY),
            _ => Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST),
        }
    }

    /// SDO read of the mapping record.
    pub fn read_mapping(&self, sub: u8, out: &mut [u8]) -> Result<usize, AbortCode> {
        if sub == 0 {
            return put(out, &[self.count]);
        }
        let e = self
            .entries
            .get(usize::from(sub) - 1)
            .ok_or(AbortCode::SUB_INDEX_DOES_NOT_EXIST)?;
        put(out, &e.to_le_bytes())
    }

    /// Size of mapping sub `sub` (all writable).
    pub fn mapping_entry(&self, sub: u8) -> Result<usize, AbortCode> {
        match sub {
            0 => Ok(1),
            s if usize::from(s) <= MAX_MAPPED => Ok(4),
            _ => Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST),
        }
    }

    /// SDO write of the mapping record, with the §7.5.2.37 procedure's rules.
    pub fn write_mapping(&mut self, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        if self.is_valid() {
            return Err(AbortCode::CANNOT_STORE_DEVICE_STATE);
        }
        if sub == 0 {
            let n = data.first().copied().unwrap_or(0);
            if usize::from(n) > MAX_MAPPED {
                return Err(AbortCode::VALUE_TOO_HIGH);
            }
            let mut bits = 0u32;
            for e in self.entries.iter().take(usize::from(n)) {
                let o = mappable(self.kind, self.direction, *e)?;
                bits += o.kind.size() as u32 * 8;
            }
            if bits > MAX_PDO_BITS {
                return Err(AbortCode::PDO_LENGTH_EXCEEDED);
            }
            self.count = n;
            return Ok(());
        }
        if self.count != 0 {
            return Err(AbortCode::CANNOT_STORE_DEVICE_STATE);
        }
        let slot = self
            .entries
            .get_mut(usize::from(sub) - 1)
            .ok_or(AbortCode::SUB_INDEX_DOES_NOT_EXIST)?;
        let v = u32::from_le_bytes(four(data));
        mappable(self.kind, self.direction, v)?;
        *slot = v;
        Ok(())
    }
}

/// Whether `id` is a CAN-ID no configurable communication object may use (CiA 301
/// §7.3.5 Table 76): 0x000 (NMT) and 0x001–0x07F, 0x101–0x180, 0x581–0x5FF (SDO server →
/// client), 0x601–0x67F (SDO client → server), 0x6E0–0x6FF, 0x701–0x77F (NMT error
/// control), 0x780–0x7FF (LSS among them).
pub const fn restricted(id: u16) -> bool {
    id <= 0x07F
        || (id >= 0x101 && id <= 0x180)
        || (id >= 0x581 && id <= 0x5FF)
        || (id >= 0x601 && id <= 0x67F)
        || (id >= 0x6E0 && id <= 0x6FF)
        || id >= 0x701
}

/// The object a mapping entry names, if it may be mapped in `direction` in a PDO of a
/// `kind` device with that bit length; else 0x06040041.
pub fn mappable(kind: DeviceKind, direction: Direction, entry: u32) -> Result<ObjectId, AbortCode> {
    let (index, sub, bits) = parse_mapping_entry(entry);
    let same =
        |o: &ObjectId| o.index == index && o.sub == sub && o.kind.size() * 8 == usize::from(bits);
    let dummies: &[ObjectId] = match direction {
        Direction::Receive => &DUMMIES,
        Direction::Transmit => &[],
    };
    direction
        .mappable(kind)
        .iter()
        .chain(dummies)
        .copied()
        .find(same)
        .ok_or(AbortCode::NOT_MAPPABLE)
}

/// Dummy entries (CiA 301 §7.4.7.1, §7.5.2.37): the data type indices 0x0002–0x0007
/// mapped into an RPDO skip that many bytes of it (another node's data in the same
/// frame). Not in TPDOs, which have nothing to fill them with.
pub const DUMMIES: [ObjectId; 6] = [
    dummy(0x0002, DataType::I8),
    dummy(0x0003, DataType::I16),
    dummy(0x0004, DataType::I32),
    dummy(0x0005, DataType::U8),
    dummy(0x0006, DataType::U16),
    dummy(0x0007, DataType::U32),
];

const fn dummy(index: u16, kind: DataType) -> ObjectId {
    ObjectId {
        index,
        sub: 0,
        kind,
        name: "Dummy",
    }
}

fn four(data: &[u8]) -> [u8; 4] {
    let mut b = [0u8; 4];
    for (d, s) in b.iter_mut().zip(data) {
        *d = *s;
    }
    b
}

fn put(out: &mut [u8], v: &[u8]) -> Result<usize, AbortCode> {
    out.get_mut(..v.len())
        .ok_or(AbortCode::OUT_OF_MEMORY)?
        .copy_from_slice(v);
    Ok(v.len())
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::cia402::objects;
    use gantry_drives::cia402::pdo::mapping_entry;

    fn e(o: ObjectId) -> [u8; 4] {
        mapping_entry(&o).to_le_bytes()
    }

    #[test]
    fn mapping_procedure_and_refusals() {
        let mut p = Pdo::synchronous(
            DeviceKind::Servo,
            Direction::Receive,
            0x201,
            &[objects::CONTROLWORD, objects::TARGET_POSITION],
        );
        assert_eq!(p.len(), 6);
        // Valid: nothing of the mapping may change.
        assert_eq!(
            p.write_mapping(0, &[0]),
            Err(AbortCode::CANNOT_STORE_DEVICE_STATE)
        );
        p.write_comm(1, &(COB_ID_INVALID | 0x201).to_le_bytes())
            .unwrap();
        // Entries only while sub 0 is 0.
        assert_eq!(
            p.write_mapping(1, &e(objects::TARGET_VELOCITY)),
            Err(AbortCode::CANNOT_STORE_DEVICE_STATE)
        );
        p.write_mapping(0, &[0]).unwrap();
        // An input object into an RPDO, a wrong bit length, an unknown object.
        assert_eq!(
            p.write_mapping(1, &e(objects::STATUSWORD)),
            Err(AbortCode::NOT_MAPPABLE)
        );
        assert_eq!(
            p.write_mapping(1, &0x6040_0020u32.to_le_bytes()),
            Err(AbortCode::NOT_MAPPABLE)
        );
        assert_eq!(
            p.write_mapping(1, &0x2000_0010u32.to_le_bytes()),
            Err(AbortCode::NOT_MAPPABLE)
        );
        assert_eq!(
            p.write_mapping(9, &e(objects::CONTROLWORD)),
            Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST)
        );
        // 2 + 4 + 2 = 8 bytes fit, + 4 do not.
        for (s, o) in [
            objects::CONTROLWORD,
            objects::TARGET_POSITION,
            objects::TARGET_TORQUE,
            objects::TARGET_VELOCITY,
        ]
        .into_iter()
        .enumerate()
        {
            p.write_mapping(s as u8 + 1, &e(o)).unwrap();
        }
        assert_eq!(
            p.write_mapping(0, &[4]),
            Err(AbortCode::PDO_LENGTH_EXCEEDED)
        );
        assert_eq!(p.write_mapping(0, &[9]), Err(AbortCode::VALUE_TOO_HIGH));
        p.write_mapping(0, &[3]).unwrap();
        assert_eq!(p.len(), 8, "2 + 4 + 2");
        assert_eq!(p.count, 3);
    }

    #[test]
    fn communication_rules() {
        let mut p = Pdo::synchronous(
            DeviceKind::Servo,
            Direction::Transmit,
            0x181,
            &[objects::STATUSWORD],
        );
        // The identifier may not change while the PDO exists; validity may.
        assert_eq!(
            p.write_comm(1, &0x182u32.to_le_bytes()),
            Err(AbortCode::INVALID_VALUE)
        );
        assert_eq!(
            p.write_comm(1, &(COB_ID_EXTENDED | 0x181).to_le_bytes()),
            Err(AbortCode::INVALID_VALUE)
        );
        assert_eq!(
            p.write_comm(3, &10u16.to_le_bytes()),
            Err(AbortCode::INVALID_VALUE),
            "inhibit time while valid"
        );
        p.write_comm(5, &10u16.to_le_bytes()).unwrap();
        for bad in [241u8, 251, 252, 253] {
            assert_eq!(p.write_comm(2, &[bad]), Err(AbortCode::INVALID_VALUE));
        }
        for good in [0u8, 1, 240, 254, 255] {
            p.write_comm(2, &[good]).unwrap();
        }
        p.write_comm(1, &(COB_ID_INVALID | 0x181).to_le_bytes())
            .unwrap();
        p.write_comm(1, &(COB_ID_INVALID | 0x281).to_le_bytes())
            .unwrap();
        p.write_comm(3, &10u16.to_le_bytes()).unwrap();
        p.write_comm(1, &0x281u32.to_le_bytes()).unwrap();
        assert!(p.is_valid());
        assert_eq!(p.can_id(), 0x281);
        assert_eq!(p.comm_entry(4), Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST));
        let r = Pdo::unused(DeviceKind::Servo, Direction::Receive, 0x201);
        assert_eq!(r.comm_entry(3), Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST));
    }
}
