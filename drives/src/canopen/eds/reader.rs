//! Reads an EDS or DCF (CiA 306-1) into an [`Eds`]. The INI layer is the `rust-ini`
//! crate (MIT), with quotes and escapes off (an EDS value is the text after `=`, a
//! backslash included) and names compared without case (vendors spell `PDOMapping`,
//! `PdoMapping`, `[1A00sub1]`, `[1A00SUB1]`). The EDS layer checks what a master relies
//! on, each failure naming the file, the line of the section and the section.

use std::collections::{BTreeMap, HashMap, HashSet};

use ini::{Ini, ParseOption};

use super::access::AccessType;
use super::data_type::DataType;
use super::device::{Commissioning, DeviceInfo, FileInfo, BAUD_RATES_KBIT};
use super::error::{EdsError, EdsErrorKind as K};
use super::object::{Object, ObjectList, ObjectType, SubObject};
use super::value::{parse_integer, Value};
use super::Eds;

/// The objects CiA 301 §7.4.5 makes mandatory.
pub const MANDATORY: [u16; 3] = [0x1000, 0x1001, 0x1018];

/// A section as read: its name as written, its line, its keys (upper case → value).
#[derive(Debug)]
struct Section {
    name: String,
    line: Option<usize>,
    keys: HashMap<String, String>,
}

struct Reader<'a> {
    file: &'a str,
    /// Upper-case name → section.
    sections: HashMap<String, Section>,
}

/// The 1-based line of each section header, in order (upper-case names), found the way
/// the INI parser finds them (a `[` after optional blanks at the start of a line).
fn section_lines(text: &str) -> Vec<(String, usize)> {
    text.lines()
        .enumerate()
        .filter_map(|(i, l)| {
            let l = l.trim_start_matches([' ', '\t']);
            let name = l.strip_prefix('[')?;
            let end = name.find(']')?;
            Some((name.get(..end)?.trim().to_ascii_uppercase(), i + 1))
        })
        .collect()
}

impl<'a> Reader<'a> {
    fn new(text: &str, file: &'a str) -> Result<Self, EdsError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let option = ParseOption {
            enabled_quote: false,
            enabled_escape: false,
            enabled_indented_mutiline_value: false,
            enabled_preserve_key_leading_whitespace: false,
        };
        let ini = Ini::load_from_str_opt(text, option).map_err(|e| EdsError {
            file: file.to_string(),
            line: Some(e.line),
            section: None,
            kind: Box::new(K::Syntax(e.msg.to_string())),
        })?;
        let lines = section_lines(text);
        let mut seen: HashMap<String, usize> = HashMap::new();
        let mut sections: HashMap<String, Section> = HashMap::new();
        for (name, props) in ini.iter() {
            let Some(name) = name else {
                if let Some((k, _)) = props.iter().next() {
                    return Err(EdsError::file(file, K::KeyOutsideSection(k.to_string())));
                }
                continue;
            };
            let upper = name.to_ascii_uppercase();
            let nth = seen.entry(upper.clone()).or_insert(0);
            let line = lines
                .iter()
                .filter(|(n, _)| *n == upper)
                .nth(*nth)
                .map(|&(_, l)| l);
            *nth += 1;
            let mut keys = HashMap::new();
            for (k, v) in props.iter() {
                if keys
                    .insert(k.to_ascii_uppercase(), v.trim().to_string())
                    .is_some()
                {
                    return Err(EdsError {
                        file: file.to_string(),
                        line,
                        section: Some(name.to_string()),
                        kind: Box::new(K::DuplicateKey(k.to_string())),
                    });
                }
            }
            if let Some(first) = sections.get(&upper) {
                return Err(EdsError {
                    file: file.to_string(),
                    line,
                    section: Some(name.to_string()),
                    kind: Box::new(K::DuplicateSection {
                        first: first.line.unwrap_or(0),
                    }),
                });
            }
            sections.insert(
                upper,
                Section {
                    name: name.to_string(),
                    line,
                    keys,
                },
            );
        }
        Ok(Self { file, sections })
    }

    fn section(&self, name: &str) -> Option<&Section> {
        self.sections.get(&name.to_ascii_uppercase())
    }

    fn err(&self, section: &str, kind: K) -> EdsError {
        let s = self.section(section);
        EdsError {
            file: self.file.to_string(),
            line: s.and_then(|s| s.line),
            section: Some(s.map_or_else(|| section.to_string(), |s| s.name.clone())),
            kind: Box::new(kind),
        }
    }

    fn get(&self, section: &str, key: &str) -> Option<&str> {
        self.section(section)?
            .keys
            .get(&key.to_ascii_uppercase())
            .map(String::as_str)
    }

    fn text(&self, section: &str, key: &str) -> String {
        self.get(section, key).unwrap_or("").to_string()
    }

    fn require(&self, section: &str, key: &str) -> Result<&str, EdsError> {
        self.get(section, key)
            .ok_or_else(|| self.err(section, K::MissingKey(key.to_string())))
    }

    /// An unsigned number no larger than `max`, if the key is there.
    fn number(
        &self,
        section: &str,
        key: &str,
        max: u64,
        what: &'static str,
    ) -> Result<Option<u64>, EdsError> {
        let Some(v) = self.get(section, key) else {
            return Ok(None);
        };
        match parse_integer(v) {
            Some(n) if (0..=i128::from(max)).contains(&n) => Ok(Some(n as u64)),
            _ => Err(self.err(
                section,
                K::BadNumber {
                    key: key.to_string(),
                    value: v.to_string(),
                    what,
                },
            )),
        }
    }

    fn u8(&self, section: &str, key: &str) -> Result<Option<u8>, EdsError> {
        Ok(self
            .number(section, key, 0xFF, "an UNSIGNED8")?
            .map(|n| n as u8))
    }

    fn u16(&self, section: &str, key: &str) -> Result<Option<u16>, EdsError> {
        Ok(self
            .number(section, key, 0xFFFF, "an UNSIGNED16")?
            .map(|n| n as u16))
    }

    fn u32(&self, section: &str, key: &str) -> Result<Option<u32>, EdsError> {
        Ok(self
            .number(section, key, 0xFFFF_FFFF, "an UNSIGNED32")?
            .map(|n| n as u32))
    }

    fn flag(&self, section: &str, key: &str) -> Result<bool, EdsError> {
        Ok(self.number(section, key, 1, "0 or 1")? == Some(1))
    }

    fn file_info(&self) -> Result<FileInfo, EdsError> {
        const S: &str = "FileInfo";
        if self.section(S).is_none() {
            return Err(self.err(S, K::MissingSection));
        }
        Ok(FileInfo {
            file_name: self.text(S, "FileName"),
            file_version: self.u8(S, "FileVersion")?.unwrap_or(0),
            file_revision: self.u8(S, "FileRevision")?.unwrap_or(0),
            eds_version: self.text(S, "EDSVersion"),
            description: self.text(S, "Description"),
            creation_time: self.text(S, "CreationTime"),
            creation_date: self.text(S, "CreationDate"),
            created_by: self.text(S, "CreatedBy"),
            modification_time: self.text(S, "ModificationTime"),
            modification_date: self.text(S, "ModificationDate"),
            modified_by: self.text(S, "ModifiedBy"),
        })
    }

    fn device_info(&self) -> Result<DeviceInfo, EdsError> {
        const S: &str = "DeviceInfo";
        if self.section(S).is_none() {
            return Err(self.err(S, K::MissingSection));
        }
        let mut baud_rates = [false; 8];
        for (on, rate) in baud_rates.iter_mut().zip(BAUD_RATES_KBIT) {
            *on = self.flag(S, &format!("BaudRate_{rate}"))?;
        }
        let pdos = |key: &str| -> Result<u16, EdsError> {
            self.require(S, key)?;
            // CiA 301: at most 512 PDOs each way (0x1400–0x15FF).
            Ok(self
                .number(S, key, 512, "a number of PDOs (0 to 512)")?
                .unwrap_or(0) as u16)
        };
        self.require(S, "Granularity")?;
        Ok(DeviceInfo {
            vendor_name: self.text(S, "VendorName"),
            vendor_number: self.u32(S, "VendorNumber")?,
            product_name: self.text(S, "ProductName"),
            product_number: self.u32(S, "ProductNumber")?,
            revision_number: self.u32(S, "RevisionNumber")?,
            order_code: self.text(S, "OrderCode"),
            baud_rates,
            simple_boot_up_master: self.flag(S, "SimpleBootUpMaster")?,
            simple_boot_up_slave: self.flag(S, "SimpleBootUpSlave")?,
            granularity: self
                .number(S, "Granularity", 64, "a granularity (0 to 64 bits)")?
                .unwrap_or(0) as u8,
            dynamic_channels_supported: self.u8(S, "DynamicChannelsSupported")?.unwrap_or(0),
            group_messaging: self.flag(S, "GroupMessaging")?,
            nr_of_rx_pdo: pdos("NrOfRXPDO")?,
            nr_of_tx_pdo: pdos("NrOfTXPDO")?,
            lss_supported: self.flag(S, "LSS_Supported")?,
        })
    }

    fn commissioning(&self) -> Result<Option<Commissioning>, EdsError> {
        let s = ["DeviceComissioning", "DeviceCommissioning"]
            .into_iter()
            .find(|s| self.section(s).is_some());
        let Some(s) = s else { return Ok(None) };
        let node = self.require(s, "NodeID")?;
        let node_id = match parse_integer(node) {
            Some(n @ 1..=127) => n as u8,
            _ => return Err(self.err(s, K::BadNodeId(node.to_string()))),
        };
        Ok(Some(Commissioning {
            node_id,
            node_name: self.text(s, "NodeName"),
            baudrate_kbit: self.u16(s, "Baudrate")?.unwrap_or(0),
            net_number: self.u32(s, "NetNumber")?.unwrap_or(0),
            network_name: self.text(s, "NetworkName"),
            canopen_manager: self.flag(s, "CANopenManager")?,
            lss_serial_number: self.u32(s, "LSS_SerialNumber")?,
        }))
    }

    fn dummy_usage(&self) -> Result<[bool; 8], EdsError> {
        let mut d = [false; 8];
        for (i, on) in d.iter_mut().enumerate().skip(1) {
            *on = self.flag("DummyUsage", &format!("Dummy{i:04X}"))?;
        }
        Ok(d)
    }

    fn comments(&self) -> Result<Vec<String>, EdsError> {
        const S: &str = "Comments";
        let n = self.u16(S, "Lines")?.unwrap_or(0);
        (1..=n)
            .map(|i| Ok(self.require(S, &format!("Line{i}"))?.to_string()))
            .collect()
    }

    /// The object lists: index → list, in the order given.
    fn lists(&self) -> Result<Vec<(u16, ObjectList)>, EdsError> {
        let mut out = Vec::new();
        let mut seen = HashSet::new();
        for list in [
            ObjectList::Mandatory,
            ObjectList::Optional,
            ObjectList::Manufacturer,
        ] {
            let s = list.section();
            if self.section(s).is_none() {
                if list == ObjectList::Mandatory {
                    return Err(self.err(s, K::MissingSection));
                }
                continue;
            }
            self.require(s, "SupportedObjects")?;
            let n = self.u16(s, "SupportedObjects")?.unwrap_or(0);
            for i in 1..=n {
                let key = i.to_string();
                let v = self.require(s, &key)?;
                let index = match parse_integer(v) {
                    Some(x @ 1..=0xFFFF) => x as u16,
                    _ => {
                        return Err(self.err(
                            s,
                            K::BadIndex {
                                key,
                                value: v.to_string(),
                            },
                        ))
                    }
                };
                if !seen.insert(index) {
                    return Err(self.err(s, K::ListedTwice(index)));
                }
                out.push((index, list));
            }
        }
        Ok(out)
    }

    fn value(
        &self,
        section: &str,
        key: &'static str,
        ty: DataType,
    ) -> Result<Option<Value>, EdsError> {
        match self.get(section, key) {
            None => Ok(None),
            Some(t) => {
                Value::parse(t, ty).map_err(|source| self.err(section, K::BadValue { key, source }))
            }
        }
    }

    fn object_type(&self, section: &str) -> Result<ObjectType, EdsError> {
        match self.get(section, "ObjectType") {
            // CiA 306-1 §4.6.3: VAR when not given.
            None => Ok(ObjectType::Var),
            Some(t) => parse_integer(t)
                .and_then(|c| u8::try_from(c).ok())
                .and_then(ObjectType::from_code)
                .ok_or_else(|| self.err(section, K::BadObjectType(t.to_string()))),
        }
    }

    fn data_type(&self, section: &str, object_type: ObjectType) -> Result<DataType, EdsError> {
        let t = match (self.get(section, "DataType"), object_type) {
            // A DOMAIN object's entry is a DOMAIN unless it says otherwise.
            (None, ObjectType::Domain) => return Ok(DataType::Domain),
            (None, _) => return Err(self.err(section, K::MissingKey("DataType".into()))),
            (Some(t), _) => t,
        };
        let code = parse_integer(t)
            .and_then(|c| u16::try_from(c).ok())
            .ok_or_else(|| {
                self.err(
                    section,
                    K::BadNumber {
                        key: "DataType".into(),
                        value: t.to_string(),
                        what: "a data type index",
                    },
                )
            })?;
        DataType::from_code(code).ok_or_else(|| self.err(section, K::NotCia301Type(code)))
    }

    /// The entry a section describes (an object's own for a VAR, or a sub-section).
    fn entry(&self, section: &str) -> Result<SubObject, EdsError> {
        let name = self.require(section, "ParameterName")?.to_string();
        let object_type = self.object_type(section)?;
        let data_type = self.data_type(section, object_type)?;
        let access = self.require(section, "AccessType")?;
        let access = AccessType::parse(access)
            .ok_or_else(|| self.err(section, K::BadAccess(access.to_string())))?;
        let pdo_mapping = self.flag(section, "PDOMapping")?;
        let entry = SubObject {
            name,
            object_type,
            data_type,
            access,
            pdo_mapping,
            default_value: self.value(section, "DefaultValue", data_type)?,
            low_limit: self.value(section, "LowLimit", data_type)?,
            high_limit: self.value(section, "HighLimit", data_type)?,
            parameter_value: self.value(section, "ParameterValue", data_type)?,
        };
        self.check_limits(section, &entry)?;
        Ok(entry)
    }

    /// `DefaultValue` and `ParameterValue` within `LowLimit..=HighLimit` (a `$NODEID`
    /// value for every node id 1..=127).
    fn check_limits(&self, section: &str, e: &SubObject) -> Result<(), EdsError> {
        if e.low_limit.is_none() && e.high_limit.is_none() {
            return Ok(());
        }
        let Some((low, high)) = e.limits() else {
            return Ok(());
        };
        for v in [&e.default_value, &e.parameter_value].into_iter().flatten() {
            for node in [1, 127] {
                if !e.allows(v, node) {
                    let value = v.integer_on(node).unwrap_or(0);
                    return Err(self.err(section, K::OutsideLimits { value, low, high }));
                }
            }
        }
        Ok(())
    }

    /// An object from its section (and its sub-sections or compact description).
    fn object(
        &self,
        index: u16,
        list: ObjectList,
        used: &mut HashSet<String>,
    ) -> Result<Object, EdsError> {
        let s = format!("{index:04X}");
        if self.section(&s).is_none() {
            return Err(self.err(list.section(), K::NoSection(index)));
        }
        used.insert(s.clone());
        let object_type = self.object_type(&s)?;
        if object_type.is_single() {
            let entry = self.entry(&s)?;
            return Ok(Object {
                index,
                name: entry.name.clone(),
                object_type,
                subs: BTreeMap::from([(0, entry)]),
                list,
            });
        }
        let name = self.require(&s, "ParameterName")?.to_string();
        let compact = self.u8(&s, "CompactSubObj")?.unwrap_or(0);
        let subs = if compact > 0 {
            self.compact(&s, &name, compact)?
        } else {
            self.sub_sections(&s, used)?
        };
        match subs.get(&0) {
            Some(z) if z.data_type == DataType::Unsigned8 => {}
            Some(z) => return Err(self.err(&s, K::SubZeroType(z.data_type.to_string()))),
            None => return Err(self.err(&s, K::SubZeroType("missing".into()))),
        }
        if object_type == ObjectType::Array {
            if let Some(first) = subs.get(&1).map(|e| e.data_type) {
                if let Some((&sub, e)) = subs.iter().find(|(&k, e)| k > 0 && e.data_type != first) {
                    return Err(self.err(
                        &format!("{s}sub{sub:X}"),
                        K::ArrayTypes {
                            sub,
                            found: e.data_type.to_string(),
                            first: first.to_string(),
                        },
                    ));
                }
            }
        }
        Ok(Object {
            index,
            name,
            object_type,
            subs,
            list,
        })
    }

    /// `[XXXXsubN]` sections, checked against `SubNumber=`.
    fn sub_sections(
        &self,
        s: &str,
        used: &mut HashSet<String>,
    ) -> Result<BTreeMap<u8, SubObject>, EdsError> {
        let declared = self
            .u8(s, "SubNumber")?
            .map(usize::from)
            .ok_or_else(|| self.err(s, K::NoSubObjects))?;
        let prefix = format!("{s}SUB");
        let mut names: Vec<(&String, &Section)> = self
            .sections
            .iter()
            .filter(|(k, _)| k.starts_with(&prefix))
            .collect();
        names.sort_by_key(|(_, sec)| sec.line);
        let mut subs = BTreeMap::new();
        for (upper, sec) in names {
            let digits = upper.get(prefix.len()..).unwrap_or("");
            let sub = u8::from_str_radix(digits, 16)
                .ok()
                .filter(|&n| n != 0xFF && !digits.is_empty() && digits.len() <= 2)
                .ok_or_else(|| self.err(&sec.name, K::BadSubIndex(digits.to_string())))?;
            subs.insert(sub, self.entry(&sec.name)?);
            used.insert(upper.clone());
        }
        if subs.len() != declared {
            return Err(self.err(
                s,
                K::SubNumber {
                    declared,
                    found: subs.len(),
                },
            ));
        }
        Ok(subs)
    }

    /// A compact ARRAY (CiA 306-1 §4.6.5, `CompactSubObj=n`): sub 0 the UNSIGNED8 `n`,
    /// subs 1..=n of the object's type, access, mapping and default, named from
    /// `[XXXXName]` (else the object's name and the sub-index), their DCF values from
    /// `[XXXXValue]`.
    fn compact(&self, s: &str, name: &str, n: u8) -> Result<BTreeMap<u8, SubObject>, EdsError> {
        let template = self.entry(s)?;
        let names = format!("{s}Name");
        let values = format!("{s}Value");
        let mut subs = BTreeMap::new();
        let count = SubObject::new("NrOfObjects", DataType::Unsigned8, AccessType::ReadOnly)
            .with_default(Value::Integer(i128::from(n)));
        subs.insert(0, count);
        for i in 1..=n {
            let key = i.to_string();
            let mut e = template.clone();
            e.object_type = ObjectType::Var;
            e.name = self
                .get(&names, &key)
                .map_or_else(|| format!("{name}{i}"), str::to_string);
            e.parameter_value = None;
            if let Some(t) = self.get(&values, &key) {
                e.parameter_value = Value::parse(t, e.data_type).map_err(|source| {
                    self.err(
                        &values,
                        K::BadValue {
                            key: "ParameterValue",
                            source,
                        },
                    )
                })?;
            }
            subs.insert(i, e);
        }
        Ok(subs)
    }

    fn objects(&self) -> Result<BTreeMap<u16, Object>, EdsError> {
        let mut used = HashSet::new();
        let mut objects = BTreeMap::new();
        for (index, list) in self.lists()? {
            objects.insert(index, self.object(index, list, &mut used)?);
        }
        // Every object section (index ≥ 0x1000; below are type definitions) belongs to
        // a listed object (CiA 306-1 §4.5: the lists name every object described).
        let mut stray: Vec<&Section> = self
            .sections
            .iter()
            .filter(|(upper, _)| !used.contains(*upper) && is_object_section(upper))
            .map(|(_, s)| s)
            .collect();
        stray.sort_by_key(|s| s.line);
        if let Some(s) = stray.first() {
            return Err(self.err(&s.name, K::Unlisted));
        }
        Ok(objects)
    }
}

/// `XXXX` or `XXXXsubN` with XXXX ≥ 0x1000.
fn is_object_section(upper: &str) -> bool {
    let (index, rest) = (upper.get(..4), upper.get(4..));
    let Some(index) = index.and_then(|i| u16::from_str_radix(i, 16).ok()) else {
        return false;
    };
    index >= 0x1000 && (rest == Some("") || rest.is_some_and(|r| r.starts_with("SUB")))
}

/// Reads `text` (the contents of `file`, whose name the errors carry).
pub fn read(text: &str, file: &str) -> Result<Eds, EdsError> {
    let r = Reader::new(text, file)?;
    let file_info = r.file_info()?;
    let device_info = r.device_info()?;
    let dummy_usage = r.dummy_usage()?;
    let comments = r.comments()?;
    let commissioning = r.commissioning()?;
    let objects = r.objects()?;
    for index in MANDATORY {
        if !objects.contains_key(&index) {
            return Err(r.err("MandatoryObjects", K::MandatoryMissing(index)));
        }
    }
    for (key, count, comm, map) in [
        ("NrOfRXPDO", device_info.nr_of_rx_pdo, 0x1400u16, 0x1600u16),
        ("NrOfTXPDO", device_info.nr_of_tx_pdo, 0x1800, 0x1A00),
    ] {
        for n in 0..count {
            for index in [comm + n, map + n] {
                if !objects.contains_key(&index) {
                    return Err(r.err("DeviceInfo", K::PdoObjectMissing { key, count, index }));
                }
            }
        }
    }
    Ok(Eds {
        file: file.to_string(),
        file_info,
        device_info,
        dummy_usage,
        comments,
        objects,
        commissioning,
    })
}

/// Reads the EDS or DCF at `path` (UTF-8, or else Latin-1 as older vendor files are).
pub fn load(path: &std::path::Path) -> Result<Eds, EdsError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| EdsError::file(&name, K::Io(e.to_string())))?;
    let text = match String::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => e.into_bytes().iter().map(|&b| char::from(b)).collect(),
    };
    read(&text, &name)
}
