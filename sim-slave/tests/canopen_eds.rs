//! The EDS the simulator writes for a node (CiA 306) agrees with the node: every object
//! the SDO server serves has its section with the server's access, size and power-on
//! value, and nothing is listed that the server does not serve.

mod canopen_common;

use std::collections::BTreeMap;

use canopen_common::*;
use gantry_drives::canopen::sdo::{Access, ObjectSize};
use gantry_sim::canopen::eds;
use gantry_sim::canopen::{CanNode, CanNodeConfig};

type Ini = BTreeMap<String, BTreeMap<String, String>>;

/// A minimal INI reader for the test (sections, key=value).
fn parse(text: &str) -> Ini {
    let mut ini = Ini::new();
    let mut section = String::new();
    for line in text.lines() {
        let line = line.trim();
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            section = name.to_string();
            assert!(
                ini.insert(section.clone(), BTreeMap::new()).is_none(),
                "section [{section}] twice"
            );
        } else if let Some((k, v)) = line.split_once('=') {
            let prev = ini
                .get_mut(&section)
                .unwrap()
                .insert(k.to_string(), v.to_string());
            assert!(prev.is_none(), "[{section}] {k} twice");
        } else {
            assert!(line.is_empty(), "stray line {line:?}");
        }
    }
    ini
}

fn size_of(code: &str) -> Option<usize> {
    match code {
        "0x0002" | "0x0005" => Some(1),
        "0x0003" | "0x0006" => Some(2),
        "0x0004" | "0x0007" => Some(4),
        "0x0009" => None,
        other => panic!("data type {other}"),
    }
}

#[test]
fn eds_describes_what_the_node_serves() {
    let mut node = CanNode::new(CanNodeConfig::servo(id(5))).unwrap();
    let text = eds::write(&mut node, "servo5.eds");
    let ini = parse(&text);
    if std::env::var_os("EDS_PRINT").is_some() {
        eprintln!("{text}");
    }
    assert_eq!(ini["FileInfo"]["EDSVersion"], "4.0");
    assert_eq!(ini["DeviceInfo"]["NrOfRXPDO"], "4");
    assert_eq!(ini["DeviceInfo"]["ProductNumber"], "0x402");
    assert_eq!(ini["MandatoryObjects"]["SupportedObjects"], "3");
    assert_eq!(ini["MandatoryObjects"]["3"], "0x1018");
    // Every sub-object section against the server.
    let mut described = Vec::new();
    for (name, keys) in &ini {
        let (index, sub) = match name.split_once("sub") {
            Some((i, s)) => (i, u8::from_str_radix(s, 16).unwrap()),
            None if name.len() == 4 && keys["ObjectType"] == "0x7" => (name.as_str(), 0),
            None => continue,
        };
        let index = u16::from_str_radix(index, 16).unwrap();
        let info = node
            .object_info(index, sub)
            .unwrap_or_else(|e| panic!("[{name}] not served: {e}"));
        let want = match info.access {
            Access::ReadOnly => "ro",
            Access::Const => "const",
            Access::WriteOnly => "wo",
            Access::ReadWrite => {
                if keys["AccessType"] == "rww" {
                    "rww"
                } else {
                    "rw"
                }
            }
        };
        assert_eq!(keys["AccessType"], want, "[{name}]");
        match (size_of(&keys["DataType"]), info.size) {
            (Some(n), ObjectSize::Fixed(m)) => assert_eq!(n, m, "[{name}] size"),
            (None, ObjectSize::Fixed(_)) => {} // a string of its fixed length
            (a, b) => panic!("[{name}] {a:?} vs {b:?}"),
        }
        described.push((index, sub));
    }
    // Nothing served is missing from the file.
    let mut served = Vec::new();
    for index in (0x1000..=0x2FFF).chain(0x6000..=0x67FF) {
        for sub in 0..=8 {
            if node.object_info(index, sub).is_ok() {
                served.push((index, sub));
            }
        }
    }
    described.sort_unstable();
    assert_eq!(described, served);
    assert!(served.len() > 150, "{} objects", served.len());
    // A few values and the PDO flags.
    assert_eq!(ini["6040"]["AccessType"], "rww");
    assert_eq!(ini["6040"]["PDOMapping"], "1");
    assert_eq!(ini["6041"]["PDOMapping"], "1");
    assert_eq!(ini["6041"]["AccessType"], "ro");
    assert_eq!(ini["6065"]["PDOMapping"], "0");
    assert_eq!(ini["605A"]["DataType"], "0x0003");
    assert_eq!(ini["605A"]["DefaultValue"], "2");
    assert_eq!(ini["1017"]["DefaultValue"], "0x64");
    assert_eq!(ini["1008"]["DefaultValue"], "gantry-sim CiA 402 servo");
    assert_eq!(ini["1600sub2"]["DefaultValue"], "0x607A0020");
    assert_eq!(ini["1400sub1"]["DefaultValue"], "0x205");
    assert_eq!(ini["1401sub1"]["DefaultValue"], "0x80000305");
    assert_eq!(ini["1800"]["SubNumber"], "6");
    // The optional and manufacturer lists name every object section once.
    let objects = ini
        .keys()
        .filter(|k| k.len() == 4 && u16::from_str_radix(k, 16).is_ok())
        .count();
    let listed: usize = ["MandatoryObjects", "OptionalObjects", "ManufacturerObjects"]
        .iter()
        .map(|s| ini[*s]["SupportedObjects"].parse::<usize>().unwrap())
        .sum();
    assert_eq!(listed, objects);
}
