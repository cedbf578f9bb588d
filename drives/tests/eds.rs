//! EDS/DCF (CiA 306-1): a vendor-shaped servo EDS read and queried (checked once by hand:
//! python-canopen 2.4.1's `import_od` reads the same file to the same data types, access,
//! PDO mapping and defaults, but for the access of the CompactSubObj sub-indices 0, which
//! it takes from the object and we give as `ro`: the count CompactSubObj fixes), round
//! trips through the writer, a DCF, the PDO mapping check, one fixture per reader error with the file,
//! line and section it names, and random input that must never panic.

use gantry_drives::canopen::eds::{
    self, AccessType, Commissioning, DataType, DcfError, EdsErrorKind as K, MappingEntry,
    MappingError, ObjectType, PdoDirection, Value,
};
use proptest::prelude::*;

const VENDOR: &str = include_str!("eds/acme_sx400.eds");

thread_local! {
    /// The vendor EDS, read once per test thread.
    static VENDOR_EDS: eds::Eds = vendor();
}

fn vendor() -> eds::Eds {
    eds::read(VENDOR, "acme_sx400.eds").unwrap_or_else(|e| panic!("{e}"))
}

fn entry(index: u16, sub: u8, bits: u8) -> MappingEntry {
    MappingEntry { index, sub, bits }
}

#[test]
fn a_vendor_servo_eds_is_read_with_what_a_master_needs() {
    let e = vendor();
    assert_eq!(e.file_info.file_version, 3);
    assert_eq!(e.file_info.modified_by, "ACME Motion GmbH");
    let d = &e.device_info;
    assert_eq!(d.vendor_number, Some(0x4A2));
    assert_eq!(d.product_number, Some(0x0040_0400));
    assert_eq!(d.granularity, 8);
    assert!(d.supports_baud_rate(1000) && d.supports_baud_rate(125));
    assert!(!d.supports_baud_rate(800));
    assert!(d.lss_supported && d.simple_boot_up_slave);
    assert_eq!(e.max_pdos(PdoDirection::Receive), 4);
    assert_eq!(e.max_pdos(PdoDirection::Transmit), 4);
    assert!(e.dummy_allowed(0x0005) && !e.dummy_allowed(0x0001));
    assert_eq!(e.comments.len(), 2);
    // Types, sizes and access for SDO.
    let cw = e.entry(0x6040, 0).unwrap();
    assert_eq!(
        (cw.data_type, cw.bits(), cw.access),
        (DataType::Unsigned16, Some(16), AccessType::ReadWriteOutput)
    );
    assert_eq!(e.entry(0x6060, 0).unwrap().data_type, DataType::Integer8);
    assert_eq!(e.entry(0x1008, 0).unwrap().bits(), None);
    assert_eq!(
        e.entry(0x1008, 0).unwrap().default_value,
        Some(Value::Text("SX400".into()))
    );
    assert_eq!(e.object(0x2100).unwrap().object_type, ObjectType::Domain);
    assert_eq!(
        e.entry(0x2200, 0).unwrap().default_value,
        Some(Value::Real(0.125))
    );
    assert_eq!(
        e.entry(0x6098, 0).unwrap().default_value,
        Some(Value::Integer(0x23))
    );
    assert_eq!(
        e.entry(0x607D, 1).unwrap().default_value,
        Some(Value::Integer(i128::from(i32::MIN)))
    );
    // $NODEID COB-IDs, both spellings.
    let cob = |i, s| e.entry(i, s).unwrap().default_value.clone().unwrap();
    assert_eq!(cob(0x1014, 0).integer_on(5), Some(0x85));
    assert_eq!(cob(0x1400, 1).integer_on(5), Some(0x205));
    assert_eq!(cob(0x1401, 1).integer_on(5), Some(0x8000_0305));
    assert_eq!(cob(0x1801, 1).integer_on(127), Some(0x8000_02FF));
    // CompactSubObj: sub 0 the count, named entries from [1010Name], else name + sub.
    let store = e.object(0x1010).unwrap();
    assert_eq!(store.subs.len(), 4);
    assert_eq!(store.sub(0).unwrap().default_value, Some(Value::Integer(3)));
    assert_eq!(store.sub(2).unwrap().name, "Save communication parameters");
    assert_eq!(store.sub(3).unwrap().access, AccessType::ReadWrite);
    let hb = e.object(0x1016).unwrap();
    assert_eq!(hb.sub(2).unwrap().name, "Consumer heartbeat time2");
    assert_eq!(hb.sub(2).unwrap().data_type, DataType::Unsigned32);
    assert_eq!(
        e.entry(0x6099, 1).unwrap().name,
        "Speed during search for switch"
    );
    // Limits.
    assert_eq!(e.entry(0x6081, 0).unwrap().limits(), Some((0, 0x0080_0000)));
    // Mapping queries.
    use PdoDirection::{Receive as R, Transmit as T};
    assert!(e.pdo_mappable(0x6040, 0, R) && !e.pdo_mappable(0x6040, 0, T));
    assert!(e.pdo_mappable(0x6064, 0, T) && !e.pdo_mappable(0x6064, 0, R));
    assert!(!e.pdo_mappable(0x6081, 0, R) && !e.pdo_mappable(0x6081, 0, T));
    assert!(e.pdo_mappable(0x2000, 3, T));
    assert!(!e.pdo_mappable(0x7000, 0, T), "no such object");
    // Every object the lists name is there, in its list.
    assert_eq!(e.objects.len(), 3 + 9 + 16 + 18 + 3);
}

#[test]
fn pdo_mappings_are_checked_against_the_eds() {
    let e = vendor();
    use PdoDirection::{Receive as R, Transmit as T};
    assert_eq!(
        e.check_pdo(R, 1, &[entry(0x6040, 0, 16), entry(0x607A, 0, 32)]),
        Ok(())
    );
    assert_eq!(
        e.check_pdo(
            T,
            4,
            &[
                entry(0x6041, 0, 16),
                entry(0x6064, 0, 32),
                entry(0x6061, 0, 8)
            ]
        ),
        Ok(())
    );
    // A dummy byte between two objects.
    assert_eq!(
        e.check_pdo(R, 2, &[entry(0x6040, 0, 16), entry(0x0005, 0, 8)]),
        Ok(())
    );
    let err = |dir, pdo, entries: &[MappingEntry]| e.check_pdo(dir, pdo, entries).unwrap_err();
    let not_mappable = err(R, 1, &[entry(0x6081, 0, 32)]);
    assert_eq!(
        not_mappable.to_string(),
        "0x6081:00 is not PDO-mappable in acme_sx400.eds"
    );
    assert_eq!(
        err(R, 1, &[entry(0x6064, 0, 32)]).to_string(),
        "0x6064:00 is ro in acme_sx400.eds: not mappable into an RPDO"
    );
    assert_eq!(
        err(T, 1, &[entry(0x6040, 0, 16)]).to_string(),
        "0x6040:00 is rww in acme_sx400.eds: not mappable into an TPDO"
    );
    assert!(matches!(
        err(R, 1, &[entry(0x6040, 0, 32)]),
        MappingError::Length {
            bits: 32,
            want: 16,
            ..
        }
    ));
    assert_eq!(
        err(T, 1, &[entry(0x6100, 0, 16)]).to_string(),
        "0x6100:00 is not in acme_sx400.eds"
    );
    assert!(matches!(
        err(R, 1, &[entry(0x0001, 0, 1)]),
        MappingError::Granularity { granularity: 8, .. }
    ));
    assert!(matches!(
        err(R, 1, &[entry(0x0002, 1, 8)]),
        MappingError::Dummy { .. }
    ));
    assert_eq!(
        err(T, 1, &[entry(0x0005, 0, 8)]).to_string(),
        "0x0005:00: acme_sx400.eds allows no dummy entry of type 0x0005 here ([DummyUsage]; RPDOs only)"
    );
    assert!(matches!(
        err(R, 1, &[entry(0x0006, 0, 8)]),
        MappingError::Length { want: 16, .. }
    ));
    assert_eq!(
        err(R, 1, &[entry(0x6040, 0, 16); 9]).to_string(),
        "RPDO 1 maps 9 objects; 0x1600 in acme_sx400.eds has 8 entries"
    );
    assert_eq!(
        err(R, 1, &[entry(0x607A, 0, 32); 3]).to_string(),
        "RPDO 1 maps 96 bits; a PDO carries at most 64"
    );
    assert_eq!(
        err(T, 5, &[]).to_string(),
        "TPDO 5 does not exist: acme_sx400.eds has 4"
    );
    assert!(matches!(err(T, 0, &[]), MappingError::NoPdo { .. }));
    // A hand-built model claiming more PDOs than CiA 301 numbers: refused, no overflow.
    let mut many = e.clone();
    many.device_info.nr_of_tx_pdo = u16::MAX;
    assert!(matches!(
        many.check_pdo(T, u16::MAX, &[]),
        Err(MappingError::NoPdo { .. })
    ));
    // A device whose mapping cannot change (Granularity=0).
    let mut fixed = e.clone();
    fixed.device_info.granularity = 0;
    assert_eq!(
        fixed
            .check_pdo(T, 1, &[entry(0x6041, 0, 16)])
            .unwrap_err()
            .to_string(),
        "0x6041:00: acme_sx400.eds has Granularity=0: its PDO mapping cannot be changed"
    );
    // The 32-bit form written to 0x1600:n, and from the drive layer's objects.
    assert_eq!(
        MappingEntry::from(gantry_drives::cia402::objects::TARGET_POSITION),
        entry(0x607A, 0, 32)
    );
    assert_eq!(MappingEntry::from_u32(0x607A_0020), entry(0x607A, 0, 32));
    assert_eq!(entry(0x6040, 0, 16).to_u32(), 0x6040_0010);
}

#[test]
fn what_is_written_reads_back_as_the_same_model() {
    let e = vendor();
    let text = eds::write_eds(&e);
    let again = eds::read(&text, "acme_sx400.eds").unwrap_or_else(|x| panic!("{x}\n{text}"));
    assert_eq!(again, e);
    // And the text is stable.
    assert_eq!(eds::write_eds(&again), text);
    // A model built in code, with every data type and a $NODEID value.
    let mut m = eds::Eds::new("built.eds");
    m.device_info.granularity = 8;
    m.dummy_usage[5] = true;
    m.comments.push("built by the test".into());
    use eds::{Object, SubObject};
    let u8ro = |name: &str, n| {
        SubObject::new(name, DataType::Unsigned8, AccessType::ReadOnly)
            .with_default(Value::Integer(n))
    };
    m.insert(Object::var(
        0x1000,
        SubObject::new("Device type", DataType::Unsigned32, AccessType::Const)
            .with_default(Value::Integer(0x191)),
    ));
    m.insert(Object::var(
        0x1001,
        SubObject::new("Error register", DataType::Unsigned8, AccessType::ReadOnly).mappable(),
    ));
    m.insert(Object::compound(
        0x1018,
        "Identity",
        ObjectType::Record,
        [
            (0, u8ro("Highest sub-index supported", 1)),
            (
                1,
                SubObject::new("Vendor-ID", DataType::Unsigned32, AccessType::ReadOnly)
                    .with_default(Value::Integer(0xA5A)),
            ),
        ],
    ));
    m.insert(Object::var(
        0x1014,
        SubObject::new("COB-ID EMCY", DataType::Unsigned32, AccessType::ReadWrite)
            .with_default(Value::NodeRelative(0x80)),
    ));
    let mut subs = vec![(0u8, u8ro("Highest sub-index supported", 25))];
    for (i, t) in eds::data_type::ALL.iter().enumerate() {
        let mut s = SubObject::new(t.name(), *t, AccessType::ReadWrite);
        s.object_type = ObjectType::Var;
        s.default_value = match t {
            DataType::Real32 | DataType::Real64 => Some(Value::Real(-2.5)),
            DataType::OctetString => Some(Value::Octets(vec![1, 0xAB])),
            DataType::VisibleString | DataType::UnicodeString | DataType::Domain => {
                Some(Value::Text("text".into()))
            }
            DataType::TimeOfDay | DataType::TimeDifference => None,
            _ => Some(Value::Integer(1)),
        };
        if t.is_integer() {
            s.low_limit = Some(Value::Integer(0));
            s.high_limit = Some(Value::Integer(1));
        }
        subs.push((i as u8 + 1, s));
    }
    m.insert(Object::compound(
        0x2000,
        "Every type",
        ObjectType::Record,
        subs,
    ));
    let back = eds::read(&eds::write_eds(&m), "built.eds").unwrap_or_else(|x| panic!("{x}"));
    assert_eq!(back, m);
}

#[test]
fn a_dcf_carries_the_commissioning_and_the_values_configured() {
    let mut e = vendor();
    e.commission(Commissioning {
        node_id: 5,
        node_name: "x axis".into(),
        baudrate_kbit: 1000,
        net_number: 1,
        network_name: "gantry".into(),
        canopen_manager: false,
        lss_serial_number: Some(0x1234),
    });
    e.set_parameter(0x1400, 1, Value::Integer(0x205)).unwrap();
    e.set_parameter(0x1017, 0, Value::Integer(100)).unwrap();
    e.set_parameter_bytes(0x6081, 0, &0x0001_0000u32.to_le_bytes())
        .unwrap();
    e.set_parameter_bytes(0x1600, 1, &0x6040_0010u32.to_le_bytes())
        .unwrap();
    // What cannot be configured.
    assert!(matches!(
        e.set_parameter(0x6041, 0, Value::Integer(0)),
        Err(DcfError::NotWritable { .. })
    ));
    assert!(matches!(
        e.set_parameter(0x1017, 0, Value::Integer(70_000)),
        Err(DcfError::Value { .. })
    ));
    assert_eq!(
        e.set_parameter(0x6081, 0, Value::Integer(0x0100_0000))
            .unwrap_err()
            .to_string(),
        "0x6081:00: 16777216 is outside 0..=8388608 in acme_sx400.eds"
    );
    assert!(matches!(
        e.set_parameter(0x6200, 0, Value::Integer(0)),
        Err(DcfError::NoObject { .. })
    ));
    assert!(e.set_parameter_bytes(0x1017, 0, &[1, 2, 3]).is_err());
    let dcf = eds::write_dcf(&e);
    assert!(dcf.contains("[DeviceComissioning]\nNodeID=5\n"), "{dcf}");
    assert!(dcf.contains("Baudrate=1000\n"));
    let back = eds::read(&dcf, "acme_sx400.eds").unwrap_or_else(|x| panic!("{x}"));
    assert_eq!(back, e);
    assert_eq!(
        back.entry(0x1017, 0).unwrap().parameter_value,
        Some(Value::Integer(100))
    );
    assert_eq!(back.commissioning.as_ref().unwrap().node_id, 5);
    // The EDS of the same model has neither.
    let plain = eds::write_eds(&e);
    assert!(!plain.contains("ParameterValue") && !plain.contains("DeviceComissioning"));
}

/// A small valid EDS the error fixtures change one thing in.
const MINI: &str = "\
[FileInfo]
FileName=mini.eds
EDSVersion=4.0

[DeviceInfo]
VendorName=test
Granularity=8
NrOfRXPDO=1
NrOfTXPDO=0

[MandatoryObjects]
SupportedObjects=3
1=0x1000
2=0x1001
3=0x1018

[OptionalObjects]
SupportedObjects=3
1=0x1400
2=0x1600
3=0x6040

[ManufacturerObjects]
SupportedObjects=1
1=0x2000

[1000]
ParameterName=Device type
DataType=0x0007
AccessType=ro
DefaultValue=0x00020192

[1001]
ParameterName=Error register
ObjectType=0x7
DataType=0x0005
AccessType=ro

[1018]
ParameterName=Identity
ObjectType=0x9
SubNumber=2

[1018sub0]
ParameterName=Highest sub-index supported
DataType=0x0005
AccessType=ro
DefaultValue=1

[1018sub1]
ParameterName=Vendor-ID
DataType=0x0007
AccessType=ro

[1400]
ParameterName=RPDO1 communication
ObjectType=0x9
SubNumber=2

[1400sub0]
ParameterName=Highest sub-index supported
DataType=0x0005
AccessType=ro
DefaultValue=1

[1400sub1]
ParameterName=COB-ID
DataType=0x0007
AccessType=rw
DefaultValue=$NODEID+0x200

[1600]
ParameterName=RPDO1 mapping
ObjectType=0x8
SubNumber=2

[1600sub0]
ParameterName=Number of entries
DataType=0x0005
AccessType=rw
DefaultValue=1

[1600sub1]
ParameterName=Entry 1
DataType=0x0007
AccessType=rw
DefaultValue=0x60400010

[6040]
ParameterName=Controlword
DataType=0x0006
AccessType=rww
PDOMapping=1

[2000]
ParameterName=Gain
DataType=0x0003
AccessType=rw
DefaultValue=10
LowLimit=0
HighLimit=100
";

/// The 1-based line of the first line that is `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l == needle)
        .map(|i| i + 1)
        .unwrap_or_else(|| panic!("{needle} not in the fixture"))
}

fn fails(text: &str) -> eds::EdsError {
    match eds::read(text, "mini.eds") {
        Ok(_) => panic!("read:\n{text}"),
        Err(e) => e,
    }
}

#[test]
fn the_error_fixtures_base_is_valid() {
    let e = eds::read(MINI, "mini.eds").unwrap_or_else(|x| panic!("{x}"));
    assert_eq!(e.objects.len(), 7);
    assert_eq!(e.entry(0x1000, 0).unwrap().object_type, ObjectType::Var);
}

#[test]
fn each_error_names_file_line_and_section() {
    // (what is replaced, by what, the section whose line the error names, the message)
    let cases: &[(&str, &str, &str, &str)] = &[
        (
            "[6040]\nParameterName=Controlword\nDataType=0x0006",
            "[6040]\nParameterName=Controlword\nDataType=0x0099",
            "[6040]",
            "DataType 0x0099 is not a CiA 301 type",
        ),
        (
            "DataType=0x0006\nAccessType=rww",
            "DataType=0x0006\nAccessType=rx",
            "[6040]",
            "AccessType rx is not one of ro, wo, rw, rwr, rww, const",
        ),
        (
            "ParameterName=Error register\nObjectType=0x7",
            "ParameterName=Error register\nObjectType=0x3",
            "[1001]",
            "ObjectType 0x3 is not a CiA 301 object type (0x0, 0x2, 0x5–0x9)",
        ),
        (
            "[6040]\nParameterName=Controlword\n",
            "[6040]\n",
            "[6040]",
            "ParameterName is missing",
        ),
        (
            "ParameterName=Controlword\nDataType=0x0006\n",
            "ParameterName=Controlword\n",
            "[6040]",
            "DataType is missing",
        ),
        (
            "AccessType=ro\nDefaultValue=1\n\n[1018sub1]",
            "AccessType=ro\nDefaultValue=300\n\n[1018sub1]",
            "[1018sub0]",
            "DefaultValue: 300 does not fit UNSIGNED8",
        ),
        (
            "DefaultValue=10\nLowLimit",
            "DefaultValue=101\nLowLimit",
            "[2000]",
            "DefaultValue 101 is outside LowLimit..=HighLimit (0..=100)",
        ),
        (
            "ObjectType=0x9\nSubNumber=2\n\n[1018sub0]",
            "ObjectType=0x9\nSubNumber=3\n\n[1018sub0]",
            "[1018]",
            "SubNumber=3 but 2 sub-index sections",
        ),
        (
            "[1400sub0]\nParameterName=Highest sub-index supported\nDataType=0x0005",
            "[1400sub0]\nParameterName=Highest sub-index supported\nDataType=0x0006",
            "[1400]",
            "sub-index 0 of an ARRAY or RECORD must be an UNSIGNED8 (highest sub-index), not UNSIGNED16",
        ),
        (
            "3=0x6040\n",
            "3=0x6041\n",
            "[OptionalObjects]",
            "0x6041 is listed but has no section",
        ),
        (
            "3=0x6040\n",
            "3=0x1400\n",
            "[OptionalObjects]",
            "0x1400 is listed twice",
        ),
        (
            "SupportedObjects=3\n1=0x1400\n2=0x1600\n3=0x6040",
            "SupportedObjects=2\n1=0x1400\n2=0x1600",
            "[6040]",
            "object section not named in any of MandatoryObjects, OptionalObjects, ManufacturerObjects",
        ),
        (
            "NrOfRXPDO=1\nNrOfTXPDO=0",
            "NrOfRXPDO=1\nNrOfTXPDO=1",
            "[DeviceInfo]",
            "NrOfTXPDO=1 but 0x1800 is not described",
        ),
        (
            "[6040]\nParameterName=Controlword",
            "[6040]\nParameterName=Controlword\nParameterName=Again",
            "[6040]",
            "ParameterName appears twice",
        ),
        (
            "NrOfRXPDO=1\n",
            "NrOfRXPDO=x1\n",
            "[DeviceInfo]",
            "NrOfRXPDO=x1 is not a number of PDOs (0 to 512)",
        ),
        (
            "VendorName=test\nGranularity=8\n",
            "VendorName=test\n",
            "[DeviceInfo]",
            "Granularity is missing",
        ),
        (
            "[1018sub1]",
            "[1018subZZ]",
            "[1018subZZ]",
            "sub-index ZZ is not a sub-index (hex, 0 to FE)",
        ),
        (
            "3=0x6040\n",
            "3=0xZZ\n",
            "[OptionalObjects]",
            "3=0xZZ is not an object index",
        ),
        (
            "ObjectType=0x8\nSubNumber=2\n",
            "ObjectType=0x8\n",
            "[1600]",
            "an ARRAY or RECORD needs SubNumber or CompactSubObj",
        ),
        (
            "DefaultValue=$NODEID+0x200",
            "DefaultValue=$NODEID*2",
            "[1400sub1]",
            "DefaultValue: \"$NODEID*2\" is not a number",
        ),
        (
            "PDOMapping=1\n",
            "PDOMapping=yes\n",
            "[6040]",
            "PDOMapping=yes is not 0 or 1",
        ),
    ];
    for (from, to, section, message) in cases {
        assert!(MINI.contains(from), "fixture lacks {from:?}");
        let text = MINI.replacen(from, to, 1);
        let e = fails(&text);
        let line = line_of(&text, section);
        let name = section.trim_matches(['[', ']']);
        assert_eq!(
            e.to_string(),
            format!("mini.eds:{line}: [{name}]: {message}"),
            "{to:?}"
        );
    }
}

#[test]
fn section_and_key_names_are_compared_without_case() {
    let base = eds::read(MINI, "mini.eds").unwrap();
    let varied = MINI
        .replacen("[1018sub1]", "[1018SUB1]", 1)
        .replacen("[DeviceInfo]", "[deviceinfo]", 1)
        .replacen(
            "DataType=0x0006\nAccessType=rww\nPDOMapping=1",
            "datatype=0x0006\nAccessType=RWW\nPdoMapping=1",
            1,
        );
    assert_ne!(varied, MINI);
    assert_eq!(eds::read(&varied, "mini.eds").unwrap(), base);
}

#[test]
fn array_entries_share_one_type() {
    let text = MINI.replacen(
        "SubNumber=2\n\n[1600sub0]",
        "SubNumber=3\n\n[1600sub2]\nParameterName=Entry 2\nDataType=0x0006\nAccessType=rw\n\n[1600sub0]",
        1,
    );
    let e = fails(&text);
    assert_eq!(
        e.to_string(),
        format!(
            "mini.eds:{}: [1600sub2]: ARRAY entry 2 is UNSIGNED16, entry 1 is UNSIGNED32",
            line_of(&text, "[1600sub2]")
        )
    );
}

#[test]
fn file_level_errors() {
    // A section twice: the second is named, with the line of the first.
    let text = format!("{MINI}\n[6040]\nParameterName=x\n");
    let e = fails(&text);
    let first = line_of(MINI, "[6040]");
    assert_eq!(
        e.to_string(),
        format!(
            "mini.eds:{}: [6040]: section appears again (first at line {first})",
            text.lines().count() - 1
        )
    );
    // A key before any section.
    let e = fails(&format!("Stray=1\n{MINI}"));
    assert_eq!(e.to_string(), "mini.eds: Stray is outside any section");
    // Not INI: the parser's line.
    let e = fails("[FileInfo]\nFileName=x\n=oops\n");
    assert_eq!(e.to_string(), "mini.eds:3: INI syntax: missing key");
    let e = fails("[FileInfo]\nFileName=x\n[DeviceInfo\n");
    assert!(matches!(*e.kind, K::Syntax(_)), "{e}");
    // A mandatory section.
    let e = fails(&MINI.replacen("[DeviceInfo]", "[DeviceInformation]", 1));
    assert_eq!(e.to_string(), "mini.eds: [DeviceInfo]: missing section");
    // A mandatory object (listed elsewhere, so its section is used).
    let text = MINI
        .replacen(
            "SupportedObjects=3\n1=0x1000\n2=0x1001\n3=0x1018",
            "SupportedObjects=2\n1=0x1000\n2=0x1018",
            1,
        )
        .replacen("[1001]", "[1001x]", 1);
    let e = fails(&text);
    assert_eq!(
        e.to_string(),
        format!(
            "mini.eds:{}: [MandatoryObjects]: 0x1001 is mandatory (CiA 301 §7.4.5) and not described",
            line_of(&text, "[MandatoryObjects]")
        )
    );
    // A DCF's node id.
    let e = fails(&format!("{MINI}\n[DeviceComissioning]\nNodeID=128\n"));
    assert!(matches!(*e.kind, K::BadNodeId(_)), "{e}");
    // $NODEID in a string.
    let e = fails(&MINI.replacen("ParameterName=Gain\nDataType=0x0003\nAccessType=rw\nDefaultValue=10\nLowLimit=0\nHighLimit=100", "ParameterName=Gain\nDataType=0x0009\nAccessType=rw\nDefaultValue=$NODEID", 1));
    assert!(
        e.to_string()
            .ends_with("DefaultValue: $NODEID: $NODEID in a VISIBLE_STRING"),
        "{e}"
    );
    // A file that cannot be read.
    let e = eds::load(std::path::Path::new("/nonexistent/x.eds")).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("/nonexistent/x.eds: cannot read: "),
        "{e}"
    );
}

#[test]
fn latin1_files_and_byte_order_marks_are_read() {
    let dir = std::env::temp_dir().join(format!("gantry-eds-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("latin1.eds");
    let mut bytes = MINI
        .replacen("VendorName=test", "VendorName=M\u{fc}ller", 1)
        .into_bytes();
    // ü as Latin-1 (one byte 0xFC), not UTF-8.
    let at = bytes.windows(2).position(|w| w == "ü".as_bytes()).unwrap();
    bytes.splice(at..at + 2, [0xFC]);
    std::fs::write(&path, &bytes).unwrap();
    let e = eds::load(&path).unwrap_or_else(|x| panic!("{x}"));
    assert_eq!(e.device_info.vendor_name, "Müller");
    let bom = format!("\u{feff}{MINI}");
    assert!(eds::read(&bom, "bom.eds").is_ok());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// EDS-like lines: sections, keys and values that the reader acts on, and junk.
fn eds_line() -> impl Strategy<Value = String> {
    let section = prop::sample::select(vec![
        "FileInfo",
        "DeviceInfo",
        "MandatoryObjects",
        "OptionalObjects",
        "ManufacturerObjects",
        "DummyUsage",
        "Comments",
        "DeviceComissioning",
        "1000",
        "1001",
        "1018",
        "1018sub0",
        "1018sub1",
        "1400",
        "1400sub1",
        "1600",
        "1600sub0",
        "6040",
        "6040Name",
        "6040Value",
        "1016",
        "1016Name",
    ]);
    let key = prop::sample::select(vec![
        "ParameterName",
        "ObjectType",
        "DataType",
        "AccessType",
        "DefaultValue",
        "PDOMapping",
        "SubNumber",
        "CompactSubObj",
        "LowLimit",
        "HighLimit",
        "ParameterValue",
        "SupportedObjects",
        "1",
        "2",
        "3",
        "NrOfRXPDO",
        "NrOfTXPDO",
        "Granularity",
        "NodeID",
        "Lines",
        "Line1",
        "NrOfEntries",
        "Dummy0005",
    ]);
    let value = prop::sample::select(vec![
        "0x1000",
        "0x1001",
        "0x1018",
        "0x1400",
        "0x1600",
        "0x6040",
        "0x7",
        "0x8",
        "0x9",
        "0x0005",
        "0x0007",
        "0x0099",
        "rw",
        "ro",
        "rww",
        "1",
        "0",
        "2",
        "255",
        "-1",
        "$NODEID",
        "$NODEID+0x200",
        "0xFFFFFFFFFFFFFFFFFFFFFFFFFFFFFFFF",
        "",
        "x",
        "08",
        "3.5",
    ]);
    prop_oneof![
        section.prop_map(|s| format!("[{s}]")),
        (key, value).prop_map(|(k, v)| format!("{k}={v}")),
        "\\PC{0,20}",
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// Any text: an EDS or an error, never a panic.
    #[test]
    fn random_text_never_panics(text in "\\PC{0,400}") {
        let _ = eds::read(&text, "random.eds");
    }

    /// Any value text for any type, any bytes for any type, any mapping: a value or an
    /// error, never a panic.
    #[test]
    fn values_and_mappings_never_panic(
        text in "\\PC{0,30}",
        bytes in prop::collection::vec(any::<u8>(), 0..12),
        code in 0u16..0x30,
        node in any::<u8>(),
        receive in any::<bool>(),
        pdo in any::<u16>(),
        raw in prop::collection::vec(any::<u32>(), 0..12),
    ) {
        if let Some(ty) = DataType::from_code(code) {
            if let Ok(Some(v)) = Value::parse(&text, ty) {
                let _ = v.to_le_bytes(ty, node);
                // Written and read back, the same value (compared as written: NaN).
                let back = Value::parse(&v.to_eds(ty), ty);
                prop_assert_eq!(back.map(|b| b.map(|b| b.to_eds(ty))), Ok(Some(v.to_eds(ty))));
            }
            if let Ok(v) = Value::from_le_bytes(&bytes, ty) {
                let _ = v.to_le_bytes(ty, node);
            }
        }
        let dir = if receive { PdoDirection::Receive } else { PdoDirection::Transmit };
        let entries: Vec<MappingEntry> = raw.iter().map(|&r| MappingEntry::from_u32(r)).collect();
        let _ = VENDOR_EDS.with(|e| e.check_pdo(dir, pdo, &entries));
    }

    /// Near-EDS text (the reader's own vocabulary): never a panic; what it accepts it
    /// writes back to the same model.
    #[test]
    fn eds_like_text_never_panics_and_round_trips(lines in prop::collection::vec(eds_line(), 0..120)) {
        let text = format!("{MINI}\n{}", lines.join("\n"));
        if let Ok(e) = eds::read(&text, "mini.eds") {
            let back = eds::read(&eds::write_dcf(&e), "mini.eds");
            prop_assert_eq!(back.as_ref().ok(), Some(&e), "{:?}", back.as_ref().err());
        }
    }

}

proptest! {
    // Each case reads the 1460-line vendor file: fewer cases, each a whole file.
    #![proptest_config(ProptestConfig::with_cases(150))]

    /// The vendor file with one line dropped or replaced: never a panic.
    #[test]
    fn a_damaged_vendor_file_never_panics(at in 0usize..1460, line in eds_line(), drop in any::<bool>()) {
        let mut lines: Vec<&str> = VENDOR.split("\r\n").collect();
        if at < lines.len() {
            if drop { lines.remove(at); } else if let Some(l) = lines.get_mut(at) { *l = &line; }
        }
        let _ = eds::read(&lines.join("\r\n"), "acme_sx400.eds");
    }
}
