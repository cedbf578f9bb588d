//! The PDO mapping (0x1600…, 0x1A00…) and assignment (0x1C12, 0x1C13) objects with the
//! rules a real device enforces (CiA 301 §7.5.2, ETG.1000.6): writable only in PreOp; a
//! mapping's entries only while its count (sub 0) is 0; only mappable objects, in the
//! right direction; no more than the device's maximum. The master's downloads pass
//! through [`check`]; at PreOp → SafeOp the device reads the result with [`layout`].

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
        // Assignment: entries while the count is 0, and only mapping objects that exist.
        if sub == 0 {
            let n = value.first().copied().unwrap_or(0);
            return if (1..=n).all(|s| od.read(index, s).is_ok()) {
                Ok(())
            } else {
                Err(OdError::NotMappable)
            };
        }
        if count != Some(0) {
            return Err(OdError::WrongState);
        }
        let mapping = u16::from_le_bytes([
            value.first().copied().unwrap_or(0),
            value.get(1).copied().unwrap_or(0),
        ]);
        let expected = if index == SM2_PDO_ASSIGNMENT {
            0x1600..=0x17FF
        } else {
            0x1A00..=0x1BFF
        };
        return if expected.contains(&mapping) && od.read(mapping, 0).is_ok() {
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
            let mapping = u16::from_le_bytes([
                v.first().copied().unwrap_or(0),
                v.get(1).copied().unwrap_or(0),
            ]);
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

/// Puts `layout` into the dictionary as the power-up mapping (entry 1…n of 0x1600 and
/// 0x1A00, with spare sub-indices up to `max_entries` for the master to fill).
pub fn install(od: &mut ObjectDictionary, rules: &PdoRules, layout: &PdoLayout) {
    for (assign, mapping, objs) in [
        (SM2_PDO_ASSIGNMENT, RXPDO_MAPPING, &layout.outputs),
        (SM3_PDO_ASSIGNMENT, TXPDO_MAPPING, &layout.inputs),
    ] {
        od.insert(assign, 0, &[1], true);
        od.insert(assign, 1, &mapping.to_le_bytes(), true);
        od.insert(mapping, 0, &[objs.len() as u8], true);
        for s in 1..=rules.max_entries {
            let entry = objs
                .get(usize::from(s) - 1)
                .map_or(0, gantry_drives::cia402::pdo::mapping_entry);
            od.insert(mapping, s, &entry.to_le_bytes(), true);
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
}
