//! An object dictionary (CiA 301 §7.4): entries addressed by index and sub-index, with a
//! writability flag. The simulator's dictionaries are small, built once at start.

use gantry_drives::cia402::image;
use gantry_drives::cia402::objects;
use gantry_drives::cia402::pdo::PdoLayout;

use super::pdo::{self, PdoRules};

/// What the simulated servo lets the master map: what it understands in its process
/// data, the objects of the shared view it codes them through.
pub fn servo_pdo_rules() -> PdoRules {
    PdoRules {
        outputs: image::OUTPUT_OBJECTS.to_vec(),
        inputs: image::INPUT_OBJECTS.to_vec(),
        max_entries: 10,
        // 0x1600–0x1603 / 0x1A00–0x1A03, as CiA 402 drives commonly offer.
        pdos: 4,
        // The servo's process data buffer each way.
        max_bytes: 64,
    }
}

/// One entry.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Entry {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Value, little-endian, sized by the data type.
    pub value: Vec<u8>,
    /// Whether SDO downloads may write it.
    pub writable: bool,
    /// The values a download may write (inclusive, as a signed or unsigned integer of
    /// the entry's size); `None`: any.
    pub range: Option<(i64, i64)>,
    /// Within the range, only these values (an enumeration with gaps, e.g. 0x60D0's
    /// sources); `None`: the whole range.
    pub allowed: Option<&'static [i64]>,
    /// One-byte entries whose valid values depend on the device's configuration (0x6060
    /// modes it has, 0x6098 methods, less those a fault knob refuses): bit `v as u8` set
    /// for each value a download may write.
    pub allowed_bytes: Option<[u64; 4]>,
}

/// An object dictionary.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ObjectDictionary {
    entries: Vec<Entry>,
    /// The device's PDO rules; `None`: PDO objects are plain entries.
    pdo_rules: Option<PdoRules>,
    /// The device is in PreOp (PDO objects may change).
    pre_op: bool,
}

/// Why an access failed (maps to SDO abort codes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OdError {
    /// No object with that index (abort 0x06020000).
    NoObject,
    /// The object exists, the sub-index does not (abort 0x06090011).
    NoSubIndex,
    /// Read-only (abort 0x06010002).
    ReadOnly,
    /// The written length does not match the entry (abort 0x06070010).
    LengthMismatch,
    /// Not allowed in the device's present state (abort 0x08000022): PDO objects
    /// outside PreOp, mapping entries while the mapping is enabled.
    WrongState,
    /// The object cannot be mapped into this PDO (abort 0x06040041).
    NotMappable,
    /// More entries than the PDO holds (abort 0x06040042).
    PdoTooLong,
    /// The value is outside the object's range (abort 0x06090030).
    ValueRange,
    /// The value is above the object's maximum (abort 0x06090031): more PDOs assigned
    /// than the device has.
    ValueTooHigh,
}

impl ObjectDictionary {
    /// Adds or replaces an entry.
    pub fn insert(&mut self, index: u16, sub: u8, value: &[u8], writable: bool) {
        match self
            .entries
            .iter_mut()
            .find(|e| e.index == index && e.sub == sub)
        {
            Some(e) => {
                e.value = value.to_vec();
                e.writable = writable;
            }
            None => self.entries.push(Entry {
                index,
                sub,
                value: value.to_vec(),
                writable,
                range: None,
                allowed: None,
                allowed_bytes: None,
            }),
        }
    }

    /// Adds or replaces an entry that downloads may only set within `min..=max` (CiA 301
    /// §7.2.4.3.17: abort 0x06090030 otherwise).
    pub fn insert_ranged(&mut self, index: u16, sub: u8, value: &[u8], min: i64, max: i64) {
        self.insert(index, sub, value, true);
        if let Some(e) = self
            .entries
            .iter_mut()
            .find(|e| e.index == index && e.sub == sub)
        {
            e.range = Some((min, max));
        }
    }

    /// Adds or replaces a one-byte entry that downloads may only set to the values in
    /// `allowed` (each value `v` as bit `v as u8`; CiA 301 §7.2.4.3.17: abort 0x06090030
    /// otherwise); its range (for the EDS) spans them as signed values.
    pub fn insert_set(&mut self, index: u16, sub: u8, value: u8, allowed: [u64; 4]) {
        self.insert(index, sub, &[value], true);
        let values = (i8::MIN..=i8::MAX).filter(|v| {
            let i = (*v as u8) as usize;
            allowed
                .get(i / 64)
                .is_some_and(|w| w & (1 << (i % 64)) != 0)
        });
        let (lo, hi) = values.fold((i64::MAX, i64::MIN), |(lo, hi), v| {
            (lo.min(i64::from(v)), hi.max(i64::from(v)))
        });
        if let Some(e) = self
            .entries
            .iter_mut()
            .find(|e| e.index == index && e.sub == sub)
        {
            e.range = (lo <= hi).then_some((lo, hi));
            e.allowed_bytes = Some(allowed);
        }
    }

    /// Adds or replaces an entry that downloads may only set to one of `allowed` (abort
    /// 0x06090030 otherwise, as for a range).
    pub fn insert_enumerated(
        &mut self,
        index: u16,
        sub: u8,
        value: &[u8],
        allowed: &'static [i64],
    ) {
        let min = allowed.iter().copied().min().unwrap_or(0);
        let max = allowed.iter().copied().max().unwrap_or(0);
        self.insert_ranged(index, sub, value, min, max);
        if let Some(e) = self
            .entries
            .iter_mut()
            .find(|e| e.index == index && e.sub == sub)
        {
            e.allowed = Some(allowed);
        }
    }

    /// The device itself sets an entry's value (its live actual values, or a setting it
    /// changed), whatever its access: no allocation, the length must be the entry's.
    pub fn set(&mut self, index: u16, sub: u8, value: &[u8]) -> Result<(), OdError> {
        let e = self
            .entries
            .iter_mut()
            .find(|e| e.index == index && e.sub == sub)
            .ok_or(OdError::NoObject)?;
        if e.value.len() != value.len() {
            return Err(OdError::LengthMismatch);
        }
        e.value.copy_from_slice(value);
        Ok(())
    }

    /// The entry at `index`:`sub` (its size and access), for a server that checks before
    /// it transfers (the CANopen node's SDO server).
    pub fn entry(&self, index: u16, sub: u8) -> Result<&Entry, OdError> {
        match self
            .entries
            .iter()
            .find(|e| e.index == index && e.sub == sub)
        {
            Some(e) => Ok(e),
            None if self.entries.iter().any(|e| e.index == index) => Err(OdError::NoSubIndex),
            None => Err(OdError::NoObject),
        }
    }

    /// Every entry, in the order inserted.
    pub fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// Copies the values of `other`'s entries into the same entries here (same index,
    /// sub-index and length; others are left): a dictionary restored to a saved copy of
    /// itself without allocating (NMT reset application).
    pub fn copy_values_from(&mut self, other: &Self) {
        for (e, o) in self.entries.iter_mut().zip(&other.entries) {
            if e.index == o.index && e.sub == o.sub && e.value.len() == o.value.len() {
                e.value.copy_from_slice(&o.value);
            }
        }
    }

    /// Reads an entry.
    pub fn read(&self, index: u16, sub: u8) -> Result<&[u8], OdError> {
        match self
            .entries
            .iter()
            .find(|e| e.index == index && e.sub == sub)
        {
            Some(e) => Ok(&e.value),
            None if self.entries.iter().any(|e| e.index == index) => Err(OdError::NoSubIndex),
            None => Err(OdError::NoObject),
        }
    }

    /// Turns on the PDO rules for the mapping and assignment objects.
    pub fn set_pdo_rules(&mut self, rules: PdoRules) {
        self.pdo_rules = Some(rules);
    }

    /// The PDO rules, if any.
    pub fn pdo_rules(&self) -> Option<&PdoRules> {
        self.pdo_rules.as_ref()
    }

    /// Tells the dictionary whether the device is in PreOp.
    pub fn set_pre_op(&mut self, pre_op: bool) {
        self.pre_op = pre_op;
    }

    /// Writes an entry (same length as it has).
    pub fn write(&mut self, index: u16, sub: u8, value: &[u8]) -> Result<(), OdError> {
        if let (Some(rules), true) = (&self.pdo_rules, pdo::is_pdo_object(index)) {
            // Existence and length first, then the PDO rules.
            let e = self.read(index, sub)?;
            if e.len() != value.len() {
                return Err(OdError::LengthMismatch);
            }
            pdo::check(self, rules, self.pre_op, index, sub, value)?;
        }
        let exists = self.entries.iter().any(|e| e.index == index);
        let e = self
            .entries
            .iter_mut()
            .find(|e| e.index == index && e.sub == sub)
            .ok_or(if exists {
                OdError::NoSubIndex
            } else {
                OdError::NoObject
            })?;
        if !e.writable {
            return Err(OdError::ReadOnly);
        }
        if e.value.len() != value.len() {
            return Err(OdError::LengthMismatch);
        }
        if let Some((min, max)) = e.range {
            // Signed when the range reaches below 0, else unsigned.
            let mut b = [0u8; 8];
            let n = value.len().min(8);
            if let (Some(dst), Some(src)) = (b.get_mut(..n), value.get(..n)) {
                dst.copy_from_slice(src);
            }
            let raw = i64::from_le_bytes(b);
            let v = if min < 0 && n > 0 && n < 8 {
                let shift = 64 - 8 * n as u32;
                (raw << shift) >> shift
            } else {
                raw
            };
            if v < min || v > max || e.allowed.is_some_and(|a| !a.contains(&v)) {
                return Err(OdError::ValueRange);
            }
        }
        if let (Some(allowed), [b]) = (e.allowed_bytes, value) {
            let i = usize::from(*b);
            if allowed.get(i / 64).is_none_or(|w| w & (1 << (i % 64)) == 0) {
                return Err(OdError::ValueRange);
            }
        }
        e.value.copy_from_slice(value);
        Ok(())
    }

    /// The dictionary of a CiA-402 servo with the given identity and the PDO mapping of
    /// [`crate::plant::servo`]: RxPDO 0x1600 = controlword + target position on SM2,
    /// TxPDO 0x1A00 = statusword + position actual on SM3.
    pub fn cia402_servo(vendor: u32, product: u32, revision: u32, serial: u32) -> Self {
        let mut od = Self::default();
        od.insert(0x1000, 0, &0x0002_0192u32.to_le_bytes(), false);
        od.insert(0x1018, 0, &[4], false);
        for (sub, v) in [(1u8, vendor), (2, product), (3, revision), (4, serial)] {
            od.insert(0x1018, sub, &v.to_le_bytes(), false);
        }
        // 0x1C00 SyncManager communication type (ETG.1000.6 Table 67): 1 mailbox
        // receive, 2 mailbox send, 3 process data outputs, 4 process data inputs. Masters
        // (SOEM) read it to find which SyncManagers carry process data before they read
        // the PDO assignment 0x1C12 + n.
        od.insert(0x1C00, 0, &[4], false);
        for (sub, kind) in [(1u8, 1u8), (2, 2), (3, 3), (4, 4)] {
            od.insert(0x1C00, sub, &[kind], false);
        }
        let rules = servo_pdo_rules();
        pdo::install(&mut od, &rules, &PdoLayout::csp_minimal());
        od.set_pdo_rules(rules);
        od.insert(0x6060, 0, &[8], true);
        od.insert(0x6061, 0, &[8], false);
        // Command values: rww (CiA 402-2); a mapped RxPDO overwrites them each cycle.
        for o in [
            objects::CONTROLWORD,
            objects::TARGET_POSITION,
            objects::TARGET_VELOCITY,
            objects::TARGET_TORQUE,
            objects::TOUCH_PROBE_FUNCTION,
        ] {
            od.insert(o.index, o.sub, &vec![0; o.kind.size()], true);
        }
        // Actual values: ro. The drive's settings are added by the drive model
        // (`ServoDrive::install_objects`), with its values and ranges.
        for o in [
            objects::STATUSWORD,
            objects::POSITION_ACTUAL_VALUE,
            objects::VELOCITY_ACTUAL_VALUE,
            objects::TORQUE_ACTUAL_VALUE,
            objects::ERROR_CODE,
            objects::FOLLOWING_ERROR_ACTUAL_VALUE,
            objects::TOUCH_PROBE_STATUS,
            objects::TOUCH_PROBE_POS1_POS_VALUE,
            objects::TOUCH_PROBE_POS1_NEG_VALUE,
            objects::TOUCH_PROBE_POS2_POS_VALUE,
            objects::TOUCH_PROBE_POS2_NEG_VALUE,
            objects::DIGITAL_INPUTS,
        ] {
            od.insert(o.index, o.sub, &vec![0; o.kind.size()], false);
        }
        od
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_writes_and_errors() {
        let mut od = ObjectDictionary::cia402_servo(1, 2, 3, 4);
        assert_eq!(od.read(0x1018, 2), Ok(&2u32.to_le_bytes()[..]));
        assert_eq!(od.read(0x1C00, 0), Ok(&[4u8][..]), "four SyncManagers");
        assert_eq!(od.read(0x1C00, 3), Ok(&[3u8][..]), "SM2: outputs");
        assert_eq!(od.read(0x1C00, 4), Ok(&[4u8][..]), "SM3: inputs");
        assert_eq!(od.read(0x1018, 9), Err(OdError::NoSubIndex));
        assert_eq!(od.read(0x2000, 0), Err(OdError::NoObject));
        assert_eq!(od.write(0x1000, 0, &[0, 0, 0, 0]), Err(OdError::ReadOnly));
        assert_eq!(od.write(0x6060, 0, &[9, 9]), Err(OdError::LengthMismatch));
        od.write(0x6060, 0, &[9]).unwrap();
        assert_eq!(od.read(0x6060, 0), Ok(&[9u8][..]));
        assert_eq!(od.write(0x6041, 0, &[0, 0]), Err(OdError::ReadOnly));
        od.write(0x6040, 0, &[0x0F, 0]).unwrap();
        // The device sets read-only values; lengths still count.
        od.set(0x6041, 0, &[0x37, 0x02]).unwrap();
        assert_eq!(od.read(0x6041, 0), Ok(&[0x37u8, 0x02][..]));
        assert_eq!(od.set(0x6041, 0, &[0]), Err(OdError::LengthMismatch));
        assert_eq!(od.set(0x2000, 0, &[0]), Err(OdError::NoObject));
    }

    #[test]
    fn ranged_entries_refuse_values_outside() {
        let mut od = ObjectDictionary::default();
        od.insert_ranged(0x605A, 0, &2i16.to_le_bytes(), 0, 8);
        od.insert_ranged(0x6085, 0, &1000u32.to_le_bytes(), 1, i64::from(u32::MAX));
        od.write(0x605A, 0, &8i16.to_le_bytes()).unwrap();
        assert_eq!(
            od.write(0x605A, 0, &(-1i16).to_le_bytes()),
            Err(OdError::ValueRange)
        );
        assert_eq!(
            od.write(0x605A, 0, &9i16.to_le_bytes()),
            Err(OdError::ValueRange)
        );
        assert_eq!(od.read(0x605A, 0), Ok(&8i16.to_le_bytes()[..]));
        assert_eq!(
            od.write(0x6085, 0, &0u32.to_le_bytes()),
            Err(OdError::ValueRange)
        );
        od.write(0x6085, 0, &u32::MAX.to_le_bytes()).unwrap();
    }
}
