//! The PDO mapping (0x1600…, 0x1A00…) and assignment (0x1C12, 0x1C13) objects with the
//! rules a real device enforces (CiA 301 §7.5.2, ETG.1000.6 §5.6.7.4): writable only in
//! PreOp; a mapping's entries only while its count (sub 0) is 0, an assignment's only
//! while its count is 0; only mappable objects, in the right direction; no more entries
//! per PDO and no more PDOs per SyncManager than the device has; each assigned PDO one of
//! the device's mapping objects of that direction, at most once. The master's downloads
//! pass through [`check`]; at PreOp → SafeOp the device reads the result with [`layout`]
//! (the assigned PDOs one after the other) and the SyncManagers' lengths must be its size.

use gantry_drives::cia402::objects::{lookup, ObjectId};
use gantry_drives::cia402::pdo::{
    parse_mapping_entry, PdoLayout, RXPDO_MAPPING, SM2_PDO_ASSIGNMENT, SM3_PDO_ASSIGNMENT,
    TXPDO_MAPPING,
};

use super::od::{ObjectDictionary, OdError};

/// What a device lets the master map.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PdoRules {
    /// Objects mappable into RxPDOs (outputs).
    pub outputs: Vec<ObjectId>,
    /// Objects mappable into TxPDOs (inputs).
    pub inputs: Vec<ObjectId>,
    /// Most entries one mapping object holds.
    pub max_entries: u8,
    /// Mapping objects per direction (0x1600… and 0x1A00…), hence also the most PDOs one
    /// SyncManager's assignment (0x1C12 / 0x1C13) takes.
    pub pdos: u8,
    /// Most bytes of process data per direction (the device's SyncManager buffer):
    /// more is refused at PreOp → SafeOp (AL status 0x001D / 0x001E).
    pub max_bytes: usize,
}

/// The mapping objects `rules` gives the assignment `assign`.
fn mappings_of(rules: &PdoRules, assign: u16) -> core::ops::Range<u16> {
    let first = if assign == SM2_PDO_ASSIGNMENT {
        RXPDO_MAPPING
    } else {
        TXPDO_MAPPING
    };
    first..first + u16::from(rules.pdos)
}

fn le_u16(v: &[u8]) -> u16 {
    u16::from_le_bytes([
        v.first().copied().unwrap_or(0),
        v.get(1).copied().unwrap_or(0),
    ])
}

/// Whether `index` is a mapping or assignment object.
pub fn is_pdo_object(index: u16) -> bool {
    matches!(index, 0x1600..=0x17FF | 0x1A00..=0x1BFF)
        || index == SM2_PDO_ASSIGNMENT
        || index == SM3_PDO_ASSIGNMENT
}

/// Checks a download to a PDO object before it is written.
pub fn check(
    od: &ObjectDictionary,
    rules: &PdoRules,
    pre_op: bool,
    index: u16,
    sub: u8,
    value: &[u8],
) -> Result<(), OdError> {
    if !pre_op {
        return Err(OdError::WrongState);
    }
    let count = od.read(index, 0).ok().and_then(|v| v.first().copied());
    let is_rx = matches!(index, 0x1600..=0x17FF);
    let is_tx = matches!(index, 0x1A00..=0x1BFF);
    if !(is_rx || is_tx) {
        let allowed = mappings_of(rules, index);
        if sub == 0 {
            // ETG.1000.6 Table 73/74: sub 0 is the number of assigned PDOs; each one a
            // mapping object of this direction the device has, none twice.
            let n = value.first().copied().unwrap_or(0);
            if n > rules.pdos {
                return Err(OdError::ValueTooHigh);
            }
            let mut seen: u64 = 0;
            for s in 1..=n {
                let mapping = le_u16(od.read(index, s)?);
                let bit = 1u64 << (mapping.wrapping_sub(allowed.start) % 64);
                if !allowed.contains(&mapping) || seen & bit != 0 {
                    return Err(OdError::NotMappable);
                }
                seen |= bit;
            }
            return Ok(());
        }
        // Entries only while the assignment is off (count 0), as the mappings.
        if count != Some(0) {
            return Err(OdError::WrongState);
        }
        if sub > rules.pdos {
            return Err(OdError::NoSubIndex);
        }
        // 0 clears an entry; it may not be counted (checked at sub 0).
        let mapping = le_u16(value);
        return if mapping == 0 || (allowed.contains(&mapping) && od.read(mapping, 0).is_ok()) {
            Ok(())
        } else {
            Err(OdError::NotMappable)
        };
    }
    if sub == 0 {
        let n = value.first().copied().unwrap_or(0);
        if n > rules.max_entries {
            return Err(OdError::PdoTooLong);
        }
        // Every entry the count covers must name a mappable object.
        return (1..=n).try_for_each(|s| {
            let entry = od.read(index, s).map_err(|_| OdError::NotMappable)?;
            mappable(rules, is_rx, entry).map(|_| ())
        });
    }
    if count != Some(0) {
        return Err(OdError::WrongState);
    }
    if sub > rules.max_entries {
        return Err(OdError::NoSubIndex);
    }
    mappable(rules, is_rx, value).map(|_| ())
}

fn mappable(rules: &PdoRules, output: bool, entry: &[u8]) -> Result<ObjectId, OdError> {
    let raw = u32::from_le_bytes([
        entry.first().copied().unwrap_or(0),
        entry.get(1).copied().unwrap_or(0),
        entry.get(2).copied().unwrap_or(0),
        entry.get(3).copied().unwrap_or(0),
    ]);
    let (index, sub, bits) = parse_mapping_entry(raw);
    let allowed = if output {
        &rules.outputs
    } else {
        &rules.inputs
    };
    allowed
        .iter()
        .copied()
        .find(|o| o.index == index && o.sub == sub && o.kind.size() * 8 == bits as usize)
        .ok_or(OdError::NotMappable)
}

/// The layout the master configured: the assigned mappings' entries, in order.
pub fn layout(od: &ObjectDictionary, rules: &PdoRules) -> Result<PdoLayout, OdError> {
    let direction = |assign: u16, output: bool| -> Result<Vec<ObjectId>, OdError> {
        let mut objs = Vec::new();
        let n = od.read(assign, 0)?.first().copied().unwrap_or(0);
        for s in 1..=n {
            let v = od.read(assign, s)?;
            let mapping = le_u16(v);
            let count = od.read(mapping, 0)?.first().copied().unwrap_or(0);
            for e in 1..=count {
                let o = mappable(rules, output, od.read(mapping, e)?)?;
                objs.push(lookup(o.index, o.sub).unwrap_or(o));
            }
        }
        Ok(objs)
    };
    Ok(PdoLayout {
        outputs: direction(SM2_PDO_ASSIGNMENT, true)?,
        inputs: direction(SM3_PDO_ASSIGNMENT, false)?,
    })
}

/// Puts `layout` into the dictionary as the power-up mapping: entries 1…n of 0x1600 and
/// 0x1A00, assigned alone; every mapping object of `rules` (0x1600… and 0x1A00…, empty
/// past the first) with spare sub-indices up to `max_entries`, and the assignments'
/// sub-indices up to `pdos`, for the master to fill.
pub fn install(od: &mut ObjectDictionary, rules: &PdoRules, layout: &PdoLayout) {
    for (assign, objs) in [
        (SM2_PDO_ASSIGNMENT, &layout.outputs),
        (SM3_PDO_ASSIGNMENT, &layout.inputs),
    ] {
        let mappings = mappings_of(rules, assign);
        od.insert(assign, 0, &[1], true);
        for (s, mapping) in (1..=rules.pdos).zip(mappings.clone()) {
            let assigned = if s == 1 { mapping } else { 0 };
            od.insert(assign, s, &assigned.to_le_bytes(), true);
        }
        for mapping in mappings.clone() {
            let objs: &[ObjectId] = if mapping == mappings.start { objs } else { &[] };
            od.insert(mapping, 0, &[objs.len() as u8], true);
            for s in 1..=rules.max_entries {
                let entry = objs
                    .get(usize::from(s) - 1)
                    .map_or(0, gantry_drives::cia402::pdo::mapping_entry);
                od.insert(mapping, s, &entry.to_le_bytes(), true);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coe::od::ObjectDictionary;

    fn servo() -> ObjectDictionary {
        let mut od = ObjectDictionary::cia402_servo(1, 2, 3, 4);
        od.set_pre_op(true);
        od
    }

    fn write(od: &mut ObjectDictionary, index: u16, sub: u8, v: &[u8]) -> Result<(), OdError> {
        od.write(index, sub, v)
    }

    #[test]
    fn the_master_maps_a_layout_by_the_rules() {
        let mut od = servo();
        let layout = PdoLayout::csp();
        for w in layout.sdo_writes() {
            write(&mut od, w.index, w.sub, &w.value).unwrap();
        }
        let rules = od.pdo_rules().unwrap().clone();
        assert_eq!(super::layout(&od, &rules).unwrap(), layout);
    }

    #[test]
    fn mistakes_are_refused_with_the_device_codes() {
        let mut od = servo();
        // Entries while the mapping is enabled (count 2).
        assert_eq!(
            write(&mut od, 0x1A00, 3, &0x606C_0020u32.to_le_bytes()),
            Err(OdError::WrongState)
        );
        write(&mut od, 0x1A00, 0, &[0]).unwrap();
        // An output object in an input PDO, a wrong bit length, an unknown object.
        for bad in [0x607A_0020u32, 0x6064_0010, 0x2000_0020] {
            assert_eq!(
                write(&mut od, 0x1A00, 1, &bad.to_le_bytes()),
                Err(OdError::NotMappable),
                "{bad:#x}"
            );
        }
        assert_eq!(write(&mut od, 0x1A00, 0, &[11]), Err(OdError::PdoTooLong));
        // Count covering an entry that is not mappable (entry 3 is empty).
        assert_eq!(write(&mut od, 0x1A00, 0, &[3]), Err(OdError::NotMappable));
        write(&mut od, 0x1A00, 0, &[2]).unwrap();
        // Assignment of a TxPDO to the outputs.
        write(&mut od, 0x1C12, 0, &[0]).unwrap();
        assert_eq!(
            write(&mut od, 0x1C12, 1, &0x1A00u16.to_le_bytes()),
            Err(OdError::NotMappable)
        );
        // Outside PreOp nothing changes.
        od.set_pre_op(false);
        assert_eq!(write(&mut od, 0x1C12, 0, &[1]), Err(OdError::WrongState));
    }

    /// A layout past [`gantry_drives::cia402::pdo::ENTRIES_PER_PDO`] inputs goes into
    /// 0x1A00 and 0x1A01, both assigned to SM3; the device reads them back in order.
    #[test]
    fn a_second_pdo_is_mapped_and_assigned() {
        use gantry_drives::cia402::objects;
        let mut od = servo();
        let mut layout = PdoLayout::csp();
        layout.outputs.push(objects::TOUCH_PROBE_FUNCTION);
        layout.inputs.extend([
            objects::DIGITAL_INPUTS,
            objects::TOUCH_PROBE_STATUS,
            objects::TOUCH_PROBE_POS1_POS_VALUE,
            objects::TOUCH_PROBE_POS1_NEG_VALUE,
            objects::TOUCH_PROBE_POS2_POS_VALUE,
        ]);
        for w in layout.sdo_writes() {
            write(&mut od, w.index, w.sub, &w.value).unwrap();
        }
        assert_eq!(od.read(0x1C13, 0), Ok(&[2u8][..]));
        assert_eq!(od.read(0x1C13, 2), Ok(&0x1A01u16.to_le_bytes()[..]));
        let rules = od.pdo_rules().unwrap().clone();
        assert_eq!(super::layout(&od, &rules).unwrap(), layout);
    }

    /// ETG.1000.6 §5.6.7.4: what the assignment objects refuse.
    #[test]
    fn the_assignment_takes_the_devices_pdos_only_while_off_and_in_preop() {
        let mut od = servo();
        let rules = od.pdo_rules().unwrap().clone();
        // Entries only while the count is 0.
        assert_eq!(
            write(&mut od, 0x1C13, 2, &0x1A01u16.to_le_bytes()),
            Err(OdError::WrongState)
        );
        write(&mut od, 0x1C13, 0, &[0]).unwrap();
        // Past the device's mapping objects, the other direction, an index past the
        // assignment's sub-indices.
        let past = 0x1A00 + u16::from(rules.pdos);
        for bad in [past, 0x1601, 0x2000] {
            assert_eq!(
                write(&mut od, 0x1C13, 2, &bad.to_le_bytes()),
                Err(OdError::NotMappable),
                "{bad:#x}"
            );
        }
        assert_eq!(
            write(&mut od, 0x1C13, rules.pdos + 1, &0x1A01u16.to_le_bytes()),
            Err(OdError::NoSubIndex)
        );
        // More PDOs than the device has; one twice; an empty (0) entry.
        assert_eq!(
            write(&mut od, 0x1C13, 0, &[rules.pdos + 1]),
            Err(OdError::ValueTooHigh)
        );
        write(&mut od, 0x1C13, 2, &0x1A00u16.to_le_bytes()).unwrap();
        assert_eq!(write(&mut od, 0x1C13, 0, &[2]), Err(OdError::NotMappable));
        write(&mut od, 0x1C13, 2, &0u16.to_le_bytes()).unwrap();
        assert_eq!(write(&mut od, 0x1C13, 0, &[2]), Err(OdError::NotMappable));
        // The second PDO, with more entries than the device's limit refused.
        write(&mut od, 0x1C13, 2, &0x1A01u16.to_le_bytes()).unwrap();
        assert_eq!(
            write(&mut od, 0x1A01, 0, &[rules.max_entries + 1]),
            Err(OdError::PdoTooLong)
        );
        write(&mut od, 0x1A01, 1, &0x6077_0010u32.to_le_bytes()).unwrap();
        write(&mut od, 0x1A01, 0, &[1]).unwrap();
        write(&mut od, 0x1C13, 0, &[2]).unwrap();
        let l = super::layout(&od, &rules).unwrap();
        assert_eq!(l.inputs.len(), 3, "0x1A00's two, then 0x1A01's one");
        assert_eq!(l.inputs[2].index, 0x6077);
        // Outside PreOp the assignment is frozen.
        od.set_pre_op(false);
        assert_eq!(write(&mut od, 0x1C13, 0, &[0]), Err(OdError::WrongState));
    }
}
