//! The EDS the simulator writes for a node (CiA 306-1), read back with gantry's EDS
//! reader, agrees with the node: every object the SDO server serves is described with
//! the server's access, size and power-on value and the PDO directions its mapping rules
//! allow, nothing is described that the server does not serve, and a PDO mapping the
//! EDS check accepts the node accepts too (and the reverse).

mod canopen_common;

use canopen_common::*;
use gantry_drives::canopen::eds::{
    self, AccessType, DataType, MappingEntry, ObjectType, PdoDirection, Value,
};
use gantry_drives::canopen::sdo::{Access, ObjectSize};
use gantry_sim::canopen::eds as sim_eds;
use gantry_sim::canopen::pdo::{self, Direction};
use gantry_sim::canopen::{CanNode, CanNodeConfig, DeviceKind};
use gantry_sim::plant::switches::SwitchCam;

fn node(n: u8) -> CanNode {
    CanNode::new(CanNodeConfig::servo(id(n))).unwrap()
}

fn read(node: &mut CanNode) -> eds::Eds {
    let text = sim_eds::write(node, "servo.eds");
    if std::env::var_os("EDS_PRINT").is_some() {
        eprintln!("{text}");
    }
    eds::read(&text, "servo.eds").unwrap_or_else(|e| panic!("{e}"))
}

/// Every (index, sub) the node's SDO server serves in the ranges a node can have.
fn served(node: &CanNode) -> Vec<(u16, u8)> {
    let mut v = Vec::new();
    for index in (0x1000..=0x2FFF).chain(0x6000..=0x67FF) {
        for sub in 0..=8 {
            if node.object_info(index, sub).is_ok() {
                v.push((index, sub));
            }
        }
    }
    v
}

/// The EDS of `n` (node 5) against the node: every described entry served with the
/// access, size, PDO directions and power-on value the EDS gives, every served entry
/// described.
fn agrees_with_the_node(n: &mut CanNode) -> eds::Eds {
    let kind = n.dictionary().kind();
    let e = read(n);
    let mut described = Vec::new();
    for o in e.objects.values() {
        for (&sub, s) in &o.subs {
            described.push((o.index, sub));
            let info = n
                .object_info(o.index, sub)
                .unwrap_or_else(|a| panic!("0x{:04X}:{sub} not served: {a}", o.index));
            let place = format!("0x{:04X}:{sub:02X} {}", o.index, s.name);
            // Access: what the server enforces.
            let want = match info.access {
                Access::ReadOnly => vec![AccessType::ReadOnly],
                Access::Const => vec![AccessType::Const],
                Access::WriteOnly => vec![AccessType::WriteOnly],
                Access::ReadWrite => vec![
                    AccessType::ReadWrite,
                    AccessType::ReadWriteInput,
                    AccessType::ReadWriteOutput,
                ],
            };
            assert!(want.contains(&s.access), "{place}: {:?}", s.access);
            // Size: what the server transfers.
            match (s.data_type.bytes(), info.size) {
                (Some(a), ObjectSize::Fixed(b)) => assert_eq!(a, b, "{place}"),
                (None, ObjectSize::Fixed(_)) => assert!(
                    matches!(s.data_type, DataType::VisibleString | DataType::Domain),
                    "{place}: {:?}",
                    s.data_type
                ),
                // Any length up to a maximum the EDS has no key for: a DOMAIN.
                (None, ObjectSize::Variable { .. }) => {
                    assert_eq!(s.data_type, DataType::Domain, "{place}")
                }
                (a, b) => panic!("{place}: {a:?} vs {b:?}"),
            }
            // Mappability: the node's own rule, both ways, with the type's length.
            let bits = s.bits().unwrap_or(0);
            let raw = (u32::from(o.index) << 16) | (u32::from(sub) << 8) | bits;
            for (dir, node_dir) in [
                (PdoDirection::Receive, Direction::Receive),
                (PdoDirection::Transmit, Direction::Transmit),
            ] {
                let node_maps = bits > 0 && pdo::mappable(kind, node_dir, raw).is_ok();
                assert_eq!(s.mappable_in(dir), node_maps, "{place} {dir}");
            }
            // The power-on value, read by SDO now.
            let mut buf = [0u8; 64];
            let empty_domain = s.data_type == DataType::Domain && s.default_value.is_none();
            if let Ok(len) = n.read_object(o.index, sub, &mut buf) {
                if empty_domain && len == 0 {
                    // A DOMAIN that powers on empty has no DefaultValue.
                    continue;
                }
                let node_value = Value::from_le_bytes(&buf[..len], s.data_type).unwrap();
                let eds_value = s
                    .default_value
                    .as_ref()
                    .unwrap_or_else(|| panic!("{place}"));
                let node_id = n.node().get();
                match (eds_value.integer_on(node_id), &node_value) {
                    (Some(v), Value::Integer(w)) => assert_eq!(v, *w, "{place}"),
                    _ => assert_eq!(eds_value, &node_value, "{place}"),
                }
            }
        }
    }
    let served = served(n);
    described.sort_unstable();
    assert_eq!(described, served, "described vs served");
    assert_eq!(
        e.entry(0x1000, 0).unwrap().default_value,
        Some(Value::Integer(i128::from(kind.device_type())))
    );
    e
}

#[test]
fn the_eds_describes_what_the_node_serves_and_nothing_else() {
    let mut n = node(5);
    let e = agrees_with_the_node(&mut n);
    assert!(e.objects.values().map(|o| o.subs.len()).sum::<usize>() > 150);
    // What a master reads from it.
    assert_eq!(e.file_info.eds_version, "4.0");
    assert_eq!(e.device_info.product_number, Some(0x402));
    assert_eq!(e.max_pdos(PdoDirection::Receive), 4);
    assert_eq!(e.max_pdos(PdoDirection::Transmit), 4);
    assert_eq!(e.device_info.granularity, 8);
    let cw = e.entry(0x6040, 0).unwrap();
    assert_eq!(
        (cw.data_type, cw.access, cw.pdo_mapping),
        (DataType::Unsigned16, AccessType::ReadWriteOutput, true)
    );
    assert_eq!(e.entry(0x6041, 0).unwrap().access, AccessType::ReadOnly);
    assert!(e.pdo_mappable(0x6064, 0, PdoDirection::Transmit));
    assert!(!e.pdo_mappable(0x6065, 0, PdoDirection::Transmit));
    assert_eq!(
        e.entry(0x605A, 0).unwrap().default_value,
        Some(Value::Integer(2))
    );
    assert_eq!(
        e.entry(0x1008, 0).unwrap().default_value,
        Some(Value::Text("gantry-sim CiA 402 servo".into()))
    );
    assert_eq!(
        e.entry(0x1600, 2).unwrap().default_value,
        Some(Value::Integer(0x607A_0020))
    );
    assert_eq!(e.object(0x1800).unwrap().subs.len(), 6);
    assert_eq!(e.object(0x1018).unwrap().object_type, ObjectType::Record);
    // The predefined COB-IDs are node-relative: one file for every node id.
    assert_eq!(
        e.entry(0x1400, 1).unwrap().default_value,
        Some(Value::NodeRelative(0x200))
    );
    assert_eq!(
        e.entry(0x1401, 1).unwrap().default_value,
        Some(Value::NodeRelative(0x8000_0300))
    );
    assert_eq!(
        e.entry(0x1014, 0).unwrap().default_value,
        Some(Value::NodeRelative(0x80))
    );
    // The limits of the servo's ranged objects.
    assert_eq!(e.entry(0x6007, 0).unwrap().limits(), Some((0, 1)));
    // Homing mode (CiA 402-2 §10.4): the method within 0…37 (the reserved ones within
    // that span are refused by the node), the speeds an ARRAY.
    let method = e.entry(0x6098, 0).unwrap();
    assert_eq!(
        (method.data_type, method.limits()),
        (DataType::Integer8, Some((0, 37)))
    );
    assert_eq!(e.object(0x6099).unwrap().object_type, ObjectType::Array);
    assert_eq!(e.entry(0x6099, 2).unwrap().data_type, DataType::Unsigned32);
    assert_eq!(e.entry(0x607C, 0).unwrap().data_type, DataType::Integer32);
    assert_eq!(e.entry(0x609A, 0).unwrap().data_type, DataType::Unsigned32);
    // Modes -1 (the manufacturer's open-loop current vector) to 10 (CST); those between
    // that the drive lacks are refused by the node.
    assert_eq!(e.entry(0x6060, 0).unwrap().limits(), Some((-1, 10)));
    // The commutation objects (manufacturer-specific), typed.
    assert_eq!(e.entry(0x2100, 0).unwrap().data_type, DataType::Integer32);
    assert_eq!(e.entry(0x2101, 0).unwrap().data_type, DataType::Unsigned8);
    assert_eq!(e.entry(0x2102, 0).unwrap().limits(), Some((0, 2992)));
    assert_eq!(e.entry(0x2103, 0).unwrap().data_type, DataType::Unsigned16);
}

/// A node with eight PDOs each way (chain `pdo_count = 8`) describes them all
/// (`NrOfRXPDO`/`NrOfTXPDO` = 8, 0x1400–0x1407 … 0x1A00–0x1A07), PDOs 5–8 with the
/// power-on COB-ID 0x80000000 (invalid, no identifier: not node-relative).
#[test]
fn the_eds_lists_every_pdo_the_node_has() {
    let mut n = CanNode::new(CanNodeConfig {
        pdo_count: 8,
        ..CanNodeConfig::servo(id(5))
    })
    .unwrap();
    let e = agrees_with_the_node(&mut n);
    assert_eq!(e.max_pdos(PdoDirection::Receive), 8);
    assert_eq!(e.max_pdos(PdoDirection::Transmit), 8);
    for base in [0x1400u16, 0x1600, 0x1800, 0x1A00] {
        assert!(e.object(base + 7).is_some(), "0x{:04X}", base + 7);
        assert!(e.object(base + 8).is_none(), "0x{:04X}", base + 8);
    }
    for index in [0x1404u16, 0x1807] {
        assert_eq!(
            e.entry(index, 1).unwrap().default_value,
            Some(Value::Integer(0x8000_0000)),
            "0x{index:04X}:01"
        );
    }
    assert_eq!(
        e.entry(0x1803, 1).unwrap().default_value,
        Some(Value::NodeRelative(0x8000_0480))
    );
    // A mapping of TPDO8 the EDS check accepts.
    let statusword = MappingEntry::from_u32(0x6041_0010);
    assert!(e
        .check_pdo(PdoDirection::Transmit, 8, &[statusword])
        .is_ok());
    assert!(e
        .check_pdo(PdoDirection::Transmit, 9, &[statusword])
        .is_err());
}

/// A node with the recorder 0x2F00 (chain `recorder_bytes`) describes it as a read-only
/// DOMAIN that no PDO maps; one without it does not describe it.
#[test]
fn the_recorder_is_a_read_only_domain_in_the_eds() {
    let mut n = CanNode::new(CanNodeConfig {
        recorder_bytes: 1000,
        ..CanNodeConfig::servo(id(5))
    })
    .unwrap();
    let e = agrees_with_the_node(&mut n);
    let r = e.entry(0x2F00, 0).unwrap();
    assert_eq!(
        (r.data_type, r.access, r.pdo_mapping),
        (DataType::Domain, AccessType::ReadOnly, false)
    );
    assert!(read(&mut node(5)).entry(0x2F00, 0).is_none());
}

/// A node with the scratch 0x2F01 (chain `scratch_bytes`) describes it as a read-write
/// DOMAIN that no PDO maps; one without it does not describe it.
#[test]
fn the_scratch_is_a_read_write_domain_in_the_eds() {
    let mut n = CanNode::new(CanNodeConfig {
        scratch_bytes: 1000,
        ..CanNodeConfig::servo(id(5))
    })
    .unwrap();
    let e = agrees_with_the_node(&mut n);
    let r = e.entry(0x2F01, 0).unwrap();
    assert_eq!(
        (r.data_type, r.access, r.pdo_mapping),
        (DataType::Domain, AccessType::ReadWrite, false)
    );
    assert!(read(&mut node(5)).entry(0x2F01, 0).is_none());
}

#[test]
fn one_file_serves_every_node_id() {
    let five = sim_eds::write(&mut node(5), "servo.eds");
    let ninety = sim_eds::write(&mut node(90), "servo.eds");
    // Only the description and the serial number (0x1018:04 = node id) differ.
    let diff: Vec<(&str, &str)> = five
        .lines()
        .zip(ninety.lines())
        .filter(|(a, b)| a != b)
        .collect();
    assert_eq!(diff.len(), 2, "{diff:?}");
    assert!(diff[0].0.starts_with("Description="), "{diff:?}");
    assert_eq!(diff[1], ("DefaultValue=0x5", "DefaultValue=0x5A"));
}

#[test]
fn mappings_the_eds_check_accepts_are_what_the_node_accepts() {
    let mut n = node(3);
    let e = read(&mut n);
    // Every single-entry mapping of every entry at its type's length, both ways, and
    // the dummies.
    let mut tried = 0;
    let mut accepted = 0;
    let mut entries: Vec<(u16, u8, u8)> = e
        .objects
        .values()
        .flat_map(|o| {
            o.subs
                .iter()
                .map(move |(&sub, s)| (o.index, sub, s.bits().unwrap_or(0).min(255) as u8))
        })
        .collect();
    entries.extend((0x0001..=0x0007).map(|t| {
        let bits = DataType::from_code(t).and_then(|d| d.bits()).unwrap_or(0) as u8;
        (t, 0, bits)
    }));
    for (index, sub, bits) in entries {
        for (dir, node_dir) in [
            (PdoDirection::Receive, Direction::Receive),
            (PdoDirection::Transmit, Direction::Transmit),
        ] {
            let entry = MappingEntry { index, sub, bits };
            let eds_ok = e.check_pdo(dir, 1, &[entry]).is_ok();
            let node_ok = pdo::mappable(DeviceKind::Servo, node_dir, entry.to_u32()).is_ok();
            assert_eq!(eds_ok, node_ok, "{entry} {dir}");
            tried += 1;
            accepted += usize::from(eds_ok);
        }
    }
    assert!(accepted >= 16 + 6, "{accepted} of {tried}");
}

#[test]
fn the_encoder_and_input_module_eds_agree_with_their_nodes() {
    let mut enc = CanNode::new(CanNodeConfig::encoder(id(5), 4096, 0.0)).unwrap();
    let e = agrees_with_the_node(&mut enc);
    assert_eq!(e.device_info.product_number, Some(0x5101));
    assert!(e.pdo_mappable(0x6004, 0, PdoDirection::Transmit));
    assert!(!e.pdo_mappable(0x6003, 0, PdoDirection::Receive));
    assert_eq!(e.entry(0x6003, 0).unwrap().access, AccessType::ReadWrite);
    assert_eq!(
        e.entry(0x6001, 0).unwrap().default_value,
        Some(Value::Integer(4096))
    );
    // Its TPDO1 maps the position value; nothing can go into an RPDO but dummies.
    assert_eq!(
        e.entry(0x1A00, 1).unwrap().default_value,
        Some(Value::Integer(0x6004_0020))
    );
    let cam = SwitchCam {
        input: 0,
        from: 0,
        to: 10,
        normally_closed: false,
    };
    let mut sw = CanNode::new(CanNodeConfig::switches(id(5), id(1), &[cam]).unwrap()).unwrap();
    let e = agrees_with_the_node(&mut sw);
    let inputs = e.object(0x6000).unwrap();
    assert_eq!(inputs.object_type, ObjectType::Array);
    assert_eq!(inputs.sub(1).unwrap().name, "Read input 8-bit");
    assert!(e.pdo_mappable(0x6000, 1, PdoDirection::Transmit));
    assert_eq!(e.entry(0x6002, 1).unwrap().access, AccessType::ReadWrite);
    assert_eq!(e.device_info.product_number, Some(0x1008));
}
