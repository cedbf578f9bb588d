//! The state directory: one parameter file per axis (`NAME.params`), read whole and
//! checked ([`super::envelope`]), written atomically ([`super::atomic`]). Every save
//! rewrites the axis' whole file from what was read, changed by the caller
//! ([`Store::update`]); saves of one [`Store`] are serialised, so two parts of gantry
//! saving different parameters of the same axis (homing, commissioning) never lose each
//! other's. Blocking I/O with fsync: call it off the real-time thread (the control
//! socket's tasks do it in `spawn_blocking`).

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use super::atomic::{remove_stale_temporaries, write_atomically};
use super::envelope;
use super::error::PersistError;
use super::params::AxisParams;

/// Mode of a new parameter file: the service's user reads and writes, its group reads.
const FILE_MODE: u32 = 0o640;
/// The extension of parameter files.
pub const EXTENSION: &str = "params";

/// The state directory and its parameter files.
#[derive(Debug)]
pub struct Store {
    dir: PathBuf,
    /// Held across each read-change-write, so concurrent updates of one file are
    /// applied one after the other.
    saving: Mutex<()>,
}

impl Store {
    /// The store in `dir`, created (mode 0750) if it does not exist; temporary files left
    /// by saves that were killed are removed.
    pub fn open(dir: &Path) -> Result<Self, PersistError> {
        let dir_err = |action| {
            move |source| PersistError::Directory {
                path: dir.to_path_buf(),
                action,
                source,
            }
        };
        std::fs::DirBuilder::new()
            .recursive(true)
            .mode(0o750)
            .create(dir)
            .map_err(dir_err("cannot create it"))?;
        remove_stale_temporaries(dir).map_err(dir_err(
            "cannot clear the temporary files of interrupted saves",
        ))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            saving: Mutex::new(()),
        })
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The parameter file of `axis`: its name, with every byte but ASCII letters, digits,
    /// `-` and `_` written `%XX` (so no axis name reaches outside the directory or
    /// clashes with a temporary file).
    pub fn path_of(&self, axis: &str) -> PathBuf {
        let mut name = String::with_capacity(axis.len() + 8);
        for b in axis.bytes() {
            if b.is_ascii_alphanumeric() || b == b'-' || b == b'_' {
                name.push(char::from(b));
            } else {
                name.push_str(&format!("%{b:02X}"));
            }
        }
        self.dir.join(format!("{name}.{EXTENSION}"))
    }

    /// What is saved for `axis`: `None` when it has no file; an error naming the file
    /// when the file is damaged or unreadable (never a silent default).
    pub fn load(&self, axis: &str) -> Result<Option<AxisParams>, PersistError> {
        let path = self.path_of(axis);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => return Err(PersistError::Read { path, source }),
        };
        let (format, body) = envelope::open(&bytes).map_err(|problem| PersistError::Corrupt {
            path: path.clone(),
            problem,
        })?;
        let params: AxisParams = toml::from_str(body).map_err(|e| PersistError::Content {
            path: path.clone(),
            reason: e.message().to_string(),
        })?;
        if params.format() > format {
            return Err(PersistError::Content {
                path,
                reason: format!(
                    "it holds step-to-absolute-switch homing (step_switch, home_method), \
                     which format {format} has not (format {} has)",
                    params.format()
                ),
            });
        }
        if params.axis != axis {
            return Err(PersistError::WrongAxis {
                path,
                found: params.axis,
                expected: axis.to_string(),
            });
        }
        Ok(Some(params))
    }

    /// What is saved for each of `axes`, in order; the first damaged file stops it.
    pub fn load_all<'a>(
        &self,
        axes: impl IntoIterator<Item = &'a str>,
    ) -> Result<Vec<AxisParams>, PersistError> {
        axes.into_iter()
            .map(|a| Ok(self.load(a)?.unwrap_or_else(|| AxisParams::new(a))))
            .collect()
    }

    /// Replaces what is saved for `params.axis` (atomically and durably).
    pub fn save(&self, params: &AxisParams) -> Result<(), PersistError> {
        let _saving = self.saving.lock().unwrap_or_else(|p| p.into_inner());
        self.write(params)
    }

    /// Reads what is saved for `axis` (nothing saved: empty), lets `change` change it and
    /// saves the result if it changed; returns the result. A damaged file is not
    /// overwritten: the error names it.
    pub fn update(
        &self,
        axis: &str,
        change: impl FnOnce(&mut AxisParams),
    ) -> Result<AxisParams, PersistError> {
        let _saving = self.saving.lock().unwrap_or_else(|p| p.into_inner());
        let old = self.load(axis)?;
        let mut params = old.clone().unwrap_or_else(|| AxisParams::new(axis));
        change(&mut params);
        params.axis = axis.to_string();
        if old.as_ref() != Some(&params) {
            self.write(&params)?;
        }
        Ok(params)
    }

    fn write(&self, params: &AxisParams) -> Result<(), PersistError> {
        let path = self.path_of(&params.axis);
        let body = toml::to_string(params).map_err(|e| PersistError::Encode {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        let sealed = envelope::seal(&body, params.format());
        write_atomically(&path, sealed.as_bytes(), FILE_MODE)
            .map_err(|(step, source)| PersistError::Write { path, step, source })
    }
}

use std::os::unix::fs::DirBuilderExt;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::persist::envelope::Corruption;
    use crate::persist::params::{PositionOffset, PtpParams, ScalingStamp};
    use crate::service::protocol::HomeParams;
    use gantry_kernel::homing::MoveHome;

    fn store(tag: &str) -> Store {
        let d = std::env::temp_dir().join(format!("gantry-store-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        Store::open(&d.join("state")).unwrap()
    }

    fn full(axis: &str) -> AxisParams {
        AxisParams {
            axis: axis.into(),
            commutation_offset: Some(-123_456),
            home_method: None,
            home: Some(HomeParams::from(MoveHome::defaults(50.0, 500.0, 5000.0))),
            step_switch: None,
            ptp: Some(PtpParams {
                speed: Some(12.5),
                acceleration: None,
                deceleration: Some(300.0),
                jerk: None,
            }),
            position: Some(PositionOffset {
                offset: -1_234.000_000_1,
                scaling: ScalingStamp {
                    counts_per_motor_rev: 131_072,
                    motor_revs: 3,
                    load_revs: 1,
                    units_per_load_rev: 5.0,
                    invert: true,
                    modulo: Some(360.0),
                },
            }),
        }
    }

    #[test]
    fn what_is_saved_is_loaded_exactly() {
        let s = store("roundtrip");
        assert_eq!(s.load("x").unwrap(), None);
        let p = full("x");
        s.save(&p).unwrap();
        assert_eq!(s.load("x").unwrap(), Some(p.clone()));
        // Only the commutation offset: the rest stays absent.
        let only = AxisParams {
            commutation_offset: Some(7),
            ..AxisParams::new("y")
        };
        s.save(&only).unwrap();
        assert_eq!(s.load("y").unwrap(), Some(only));
        let all = s.load_all(["x", "y", "z"]).unwrap();
        assert_eq!(all[0], p);
        assert_eq!(all[2], AxisParams::new("z"));
        assert!(all[2].is_empty() && !all[1].is_empty());
        let _ = std::fs::remove_dir_all(s.dir().parent().unwrap());
    }

    #[test]
    fn an_update_keeps_what_others_saved() {
        let s = store("update");
        s.update("x", |p| p.commutation_offset = Some(42)).unwrap();
        let after = s
            .update("x", |p| {
                p.ptp = Some(PtpParams {
                    speed: Some(3.0),
                    ..PtpParams::default()
                })
            })
            .unwrap();
        assert_eq!(after.commutation_offset, Some(42));
        assert_eq!(s.load("x").unwrap(), Some(after));
        // Concurrent updates of different parameters: none is lost.
        let s = std::sync::Arc::new(s);
        let threads: Vec<_> = (0..8)
            .map(|i| {
                let s = s.clone();
                std::thread::spawn(move || {
                    for k in 0..10 {
                        s.update("x", |p| {
                            if i % 2 == 0 {
                                p.commutation_offset = Some(i * 100 + k)
                            } else {
                                p.ptp = Some(PtpParams {
                                    jerk: Some(f64::from(i * 100 + k)),
                                    ..PtpParams::default()
                                })
                            }
                        })
                        .unwrap();
                    }
                })
            })
            .collect();
        for t in threads {
            t.join().unwrap();
        }
        let p = s.load("x").unwrap().unwrap();
        assert_eq!(p.commutation_offset.map(|o| o % 100), Some(9), "{p:?}");
        assert_eq!(
            p.ptp.and_then(|q| q.jerk).map(|j| j % 100.0),
            Some(9.0),
            "{p:?}"
        );
        let _ = std::fs::remove_dir_all(s.dir().parent().unwrap());
    }

    #[test]
    fn axis_names_stay_inside_the_directory() {
        let s = store("names");
        assert_eq!(s.path_of("x-1_b"), s.dir().join("x-1_b.params"));
        assert_eq!(
            s.path_of("../etc/x"),
            s.dir().join("%2E%2E%2Fetc%2Fx.params")
        );
        assert_eq!(s.path_of(".x"), s.dir().join("%2Ex.params"));
        let p = full("../évil");
        s.save(&p).unwrap();
        assert_eq!(s.load("../évil").unwrap(), Some(p));
        assert_eq!(std::fs::read_dir(s.dir()).unwrap().count(), 1);
        let _ = std::fs::remove_dir_all(s.dir().parent().unwrap());
    }

    /// Every way a file can be damaged is found, and the error names the file.
    #[test]
    fn every_corruption_is_found_with_its_path() {
        let s = store("corrupt");
        let p = full("x");
        s.save(&p).unwrap();
        let path = s.path_of("x");
        let good = std::fs::read(&path).unwrap();
        let text = String::from_utf8(good.clone()).unwrap();
        let reseal = |body: &str| envelope::seal(body, 1).into_bytes();
        let body = envelope::open(&good).unwrap().1.to_string();
        let cases: Vec<(&str, Vec<u8>)> = vec![
            ("empty", Vec::new()),
            ("cut in the middle", good[..good.len() / 2].to_vec()),
            (
                "cut before the last newline",
                good[..good.len() - 1].to_vec(),
            ),
            ("cut inside the header", good[..10].to_vec()),
            ("a byte altered", {
                let mut b = good.clone();
                let i = text.find("-123456").unwrap() + 1;
                b[i] = b'9';
                b
            }),
            (
                "a line dropped",
                text.replacen("commutation_offset = -123456\n", "", 1)
                    .into_bytes(),
            ),
            ("zeros written over a block", {
                let mut b = good.clone();
                for x in &mut b[40..80] {
                    *x = 0;
                }
                b
            }),
            (
                "another format",
                text.replacen("format 1", "format 9", 1).into_bytes(),
            ),
            ("not ours", b"commutation_offset = 5\n".to_vec()),
            ("binary", vec![0xff; 64]),
            ("valid envelope, body not TOML", reseal("axis = \n")),
            (
                "valid envelope, unknown key",
                reseal(&format!("{body}\nfrobnicate = 1\n")),
            ),
            (
                "valid envelope, wrong type",
                reseal(&body.replace("-123456", "\"east\"")),
            ),
            (
                "valid envelope, offset beyond i32",
                reseal(&body.replace("-123456", "4294967296")),
            ),
            (
                "valid envelope, another axis'",
                reseal(&body.replacen("axis = \"x\"", "axis = \"y\"", 1)),
            ),
        ];
        for (what, bytes) in cases {
            std::fs::write(&path, &bytes).unwrap();
            let e = s.load("x").expect_err(what);
            assert!(e.is_corrupt(), "{what}: {e}");
            let text = e.to_string();
            assert!(text.contains(&path.display().to_string()), "{what}: {text}");
            assert!(text.contains("Move it away"), "{what}: {text}");
            // A damaged file is never overwritten by an update (it would lose what it held).
            assert!(
                s.update("x", |q| q.commutation_offset = Some(1)).is_err(),
                "{what}"
            );
            assert_eq!(std::fs::read(&path).unwrap(), bytes, "{what}");
        }
        // The kinds are told apart.
        std::fs::write(&path, &good[..good.len() - 3]).unwrap();
        assert!(matches!(
            s.load("x"),
            Err(PersistError::Corrupt {
                problem: Corruption::Truncated { .. },
                ..
            })
        ));
        std::fs::write(&path, text.replace("12.5", "12.6")).unwrap();
        assert!(matches!(
            s.load("x"),
            Err(PersistError::Corrupt {
                problem: Corruption::Checksum { .. },
                ..
            })
        ));
        let _ = std::fs::remove_dir_all(s.dir().parent().unwrap());
    }

    #[test]
    fn an_unwritable_directory_is_named() {
        let s = store("unwritable");
        std::fs::remove_dir_all(s.dir()).unwrap();
        std::fs::write(s.dir(), b"a file, not a directory").unwrap();
        let e = s.save(&full("x")).unwrap_err();
        assert!(matches!(e, PersistError::Write { .. }), "{e}");
        assert!(e.to_string().contains("x.params"), "{e}");
        let e = Store::open(s.dir()).unwrap_err();
        assert!(e.to_string().contains("state directory"), "{e}");
        let _ = std::fs::remove_dir_all(s.dir().parent().unwrap());
    }

    /// A file of format 1 as this gantry wrote it (`Store::save` of these values, byte
    /// for byte): later versions must read it as it is, and write the same bytes.
    const FORMAT_1: &str = r#"# gantry axis parameters, format 1
axis = "x"
commutation_offset = -123456

[home]
direction = "+"
switches = "ref-and-limit"
mode = "edge-2"
speed_switch = 12.5
max_distance_switch = inf
speed_reference = 1.25
max_distance_reference = inf
acceleration = 250.0
jerk = 2500.0
reference_offset = 0.0
normal_position = 0.0

[ptp]
speed = 12.5
deceleration = 300.0

[position]
offset = -1234.5

[position.scaling]
counts_per_motor_rev = 131072
motor_revs = 1
load_revs = 1
units_per_load_rev = 5.0
invert = false
# crc32 7a1f9420
"#;

    /// The parameters of [`FORMAT_2`].
    fn step_switch_params() -> AxisParams {
        use crate::service::protocol::{
            HomeMethod, StepDirection, StepSwitchMode, StepSwitchParams,
        };
        AxisParams {
            home_method: Some(HomeMethod::StepToSwitch),
            step_switch: Some(StepSwitchParams {
                direction: Some(StepDirection::SwitchNegative),
                switch_mode: Some(StepSwitchMode::EdgeSwitchPositive),
                velocity: Some(20.0),
                acceleration: Some(2500.0),
                deceleration: Some(40.0),
                jerk: Some(50000.0),
                set_position: Some(-12.5),
                distance_limit: Some(f64::INFINITY),
            }),
            commutation_offset: Some(-123_456),
            ..AxisParams::new("x")
        }
    }

    /// A file of format 2 as this gantry wrote it (`Store::save` of
    /// [`step_switch_params`], byte for byte).
    const FORMAT_2: &str = r#"# gantry axis parameters, format 2
axis = "x"
commutation_offset = -123456
home_method = "step-to-switch"

[step_switch]
direction = "switch-negative"
switch_mode = "edge-switch-positive"
velocity = 20.0
acceleration = 2500.0
deceleration = 40.0
jerk = 50000.0
set_position = -12.5
distance_limit = inf
# crc32 4a7a7f58
"#;

    #[test]
    fn a_format_2_file_reads_and_writes_byte_for_byte() {
        let s = store("fixture-2");
        let p = step_switch_params();
        s.save(&p).unwrap();
        let written = std::fs::read_to_string(s.path_of("x")).unwrap();
        assert_eq!(written, FORMAT_2);
        std::fs::write(s.path_of("x"), FORMAT_2).unwrap();
        assert_eq!(s.load("x").unwrap(), Some(p));
        let _ = std::fs::remove_dir_all(s.dir().parent().unwrap());
    }

    #[test]
    fn a_file_is_format_2_only_while_it_holds_step_switch_homing() {
        let s = store("formats");
        // Format 1 with a commutation offset; a step-to-switch homing saved: format 2,
        // the rest kept.
        s.update("x", |p| p.commutation_offset = Some(5)).unwrap();
        let first_line = || {
            let text = std::fs::read_to_string(s.path_of("x")).unwrap();
            text.lines().next().unwrap().to_string()
        };
        assert_eq!(first_line(), "# gantry axis parameters, format 1");
        let step = step_switch_params();
        s.update("x", |p| {
            p.step_switch = step.step_switch;
            p.home_method = step.home_method;
        })
        .unwrap();
        assert_eq!(first_line(), "# gantry axis parameters, format 2");
        let p = s.load("x").unwrap().unwrap();
        assert_eq!(p.commutation_offset, Some(5));
        assert_eq!(p.step_switch, step.step_switch);
        // MoveHome again: the method is MoveHome (absent), the step-to-switch set kept
        // for the next such call, so still format 2.
        s.update("x", |p| p.home_method = None).unwrap();
        assert_eq!(first_line(), "# gantry axis parameters, format 2");
        s.update("x", |p| p.step_switch = None).unwrap();
        assert_eq!(first_line(), "# gantry axis parameters, format 1");
        // A format-1 file with format 2's content (edited by hand, resealed) is refused:
        // its first line does not say what it holds.
        let body = toml::to_string(&step).unwrap();
        std::fs::write(s.path_of("x"), envelope::seal(&body, 1)).unwrap();
        let e = s.load("x").unwrap_err();
        assert!(matches!(e, PersistError::Content { .. }), "{e}");
        assert!(
            e.to_string()
                .contains("which format 1 has not (format 2 has)"),
            "{e}"
        );
        // The same body under format 2 is good.
        std::fs::write(s.path_of("x"), envelope::seal(&body, 2)).unwrap();
        assert_eq!(s.load("x").unwrap(), Some(step));
        let _ = std::fs::remove_dir_all(s.dir().parent().unwrap());
    }

    #[test]
    fn a_format_1_file_reads_and_writes_byte_for_byte() {
        let s = store("fixture");
        std::fs::write(s.path_of("x"), FORMAT_1).unwrap();
        let p = s.load("x").unwrap().unwrap();
        assert_eq!(p.commutation_offset, Some(-123_456));
        assert_eq!(
            p.home,
            Some(HomeParams::from(MoveHome::defaults(50.0, 500.0, 5000.0)))
        );
        assert_eq!(p.ptp.and_then(|q| q.deceleration), Some(300.0));
        assert_eq!(p.position.map(|o| o.offset), Some(-1234.5));
        std::fs::remove_file(s.path_of("x")).unwrap();
        s.save(&p).unwrap();
        assert_eq!(std::fs::read_to_string(s.path_of("x")).unwrap(), FORMAT_1);
        let _ = std::fs::remove_dir_all(s.dir().parent().unwrap());
    }
}
