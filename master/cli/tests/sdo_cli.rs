//! `gantry sdo upload|download` end to end, through the binary: `gantry run --no-rt` on the
//! example configuration with its simulated drives in the process, the cycle running,
//! a drive's objects read and written from the shell, by axis and by bus position; and
//! each mistake a user makes gets a clear message and a failing exit — an unknown axis,
//! a malformed INDEX:SUB, a value that does not fit its type, an object the drive does
//! not have (the drive's abort code with its CiA 301 text), a drive that is not there,
//! no service running. The service ends as usual afterwards.
//!
//! Transfers during a move, with no setpoint missed, are the lockstep test's claim
//! (`tests/tests/runtime_sdo.rs`): without real time (`--no-rt`) on a loaded host the
//! simulated drives' own clock sees the host's stalls, which a move would turn into
//! faults that are not the transfers'.

use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

fn gantry() -> Command {
    Command::new(env!("CARGO_BIN_EXE_gantry"))
}

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../deploy/examples")
        .join(name)
}

struct Service {
    child: Child,
    socket: PathBuf,
    dir: PathBuf,
}

impl Service {
    /// The example configuration as shipped, from a folder of its own.
    fn start() -> Self {
        let dir = std::env::temp_dir().join(format!("gantry-sdo-cli-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::copy(example("sim-4-axes.toml"), dir.join("gantry.toml")).unwrap();
        std::fs::copy(example("sim-4-servos.toml"), dir.join("sim-4-servos.toml")).unwrap();
        let socket = dir.join("gantry.sock");
        let child = gantry()
            .args(["run", "--no-rt", "--config"])
            .arg(dir.join("gantry.toml"))
            .arg("--socket")
            .arg(&socket)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let end = Instant::now() + Duration::from_secs(20);
        while UnixStream::connect(&socket).is_err() {
            assert!(Instant::now() < end, "the service did not open its socket");
            std::thread::sleep(Duration::from_millis(50));
        }
        Self { child, socket, dir }
    }

    fn cli(&self, args: &[&str]) -> Output {
        gantry()
            .args(args)
            .arg("--socket")
            .arg(&self.socket)
            .output()
            .unwrap()
    }

    /// A command that must succeed: its stdout, trimmed.
    fn ok(&self, args: &[&str]) -> String {
        let out = self.cli(args);
        assert!(
            out.status.success(),
            "{args:?}: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).trim().to_string()
    }

    /// A command that must fail: its stderr.
    fn fails(&self, args: &[&str]) -> String {
        let out = self.cli(args);
        assert!(!out.status.success(), "{args:?} should fail");
        let e = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(!e.contains("panicked"), "{args:?}: {e}");
        e
    }

    /// SIGTERM: the service ends as usual after the transfers (bus to PreOp, exit 0).
    fn stop(mut self) {
        nix::sys::signal::kill(
            nix::unistd::Pid::from_raw(self.child.id() as i32),
            nix::sys::signal::Signal::SIGTERM,
        )
        .unwrap();
        let end = Instant::now() + Duration::from_secs(20);
        let status = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break s;
            }
            assert!(Instant::now() < end, "the service did not stop");
            std::thread::sleep(Duration::from_millis(50));
        };
        let mut out = String::new();
        std::io::Read::read_to_string(self.child.stdout.as_mut().unwrap(), &mut out).unwrap();
        assert!(status.success(), "{out}");
        assert!(out.contains("bus: slaves in PreOp"), "{out}");
    }
}

impl Drop for Service {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

#[test]
fn gantry_sdo_reads_and_writes_a_drive_of_a_running_service() {
    let svc = Service::start();
    // The simulated servo: CiA 402, device type 0x00020192 (0x1000), CSP (0x6060 = 8).
    assert_eq!(
        svc.ok(&["sdo", "upload", "--axis", "x", "0x1000:0", "--type", "u32"]),
        0x0002_0192u32.to_string()
    );
    assert_eq!(
        svc.ok(&["sdo", "upload", "--axis", "x", "1000:00"]),
        "92010200",
        "hex by default, as on the wire"
    );
    // Its drive's mode of operation, written and read back; the same drive by its bus
    // position.
    assert_eq!(
        svc.ok(&["sdo", "upload", "--axis", "x", "0x6060:0", "--type", "i8"]),
        "8"
    );
    assert_eq!(
        svc.ok(&["sdo", "download", "--axis", "x", "0x6060:0", "8", "--type", "i8"]),
        ""
    );
    assert_eq!(
        svc.ok(&["sdo", "upload", "--drive", "0", "0x6060:0", "--type", "u8"]),
        "8"
    );
    let j: serde_json::Value = serde_json::from_str(&svc.ok(&[
        "sdo", "upload", "--axis", "y", "0x1018:0", "--type", "u8", "--json",
    ]))
    .unwrap();
    assert_eq!(
        (j["index"].as_u64(), j["sub"].as_u64()),
        (Some(0x1018), Some(0))
    );
    assert_eq!(
        (j["data"].as_str(), j["value"].as_str()),
        (Some("04"), Some("4"))
    );
    // A value of every width, written and read back: 0x6065 following error window
    // (UNSIGNED32), 0x6060 as the string of its one byte.
    svc.ok(&[
        "sdo", "download", "--axis", "z", "0x6065:0", "0x1234", "--type", "u32",
    ]);
    assert_eq!(
        svc.ok(&["sdo", "upload", "--axis", "z", "0x6065:0", "--type", "u32"]),
        "4660"
    );
    assert_eq!(
        svc.ok(&["sdo", "upload", "--axis", "z", "0x6065:0", "--type", "hex"]),
        "34120000"
    );
    let e = svc.fails(&["sdo", "upload", "--axis", "z", "0x6065:0", "--type", "u16"]);
    assert!(
        e.contains("the drive sent 4 bytes (34120000), a u16 has 2"),
        "{e}"
    );

    // The mistakes, each said plainly.
    let e = svc.fails(&["sdo", "upload", "--axis", "w", "0x6060:0"]);
    assert!(e.contains("no axis named \"w\""), "{e}");
    let e = svc.fails(&["sdo", "upload", "--axis", "x", "6060"]);
    assert!(e.contains("object \"6060\" is not INDEX:SUB"), "{e}");
    let e = svc.fails(&[
        "sdo", "download", "--axis", "x", "0x6060:0", "300", "--type", "u8",
    ]);
    assert!(
        e.contains("value \"300\" is not a u8 (out of its range)"),
        "{e}"
    );
    let e = svc.fails(&[
        "sdo", "download", "--axis", "x", "0x6060:0", "8", "--type", "u9",
    ]);
    assert!(e.contains("type \"u9\" is not one of u8, u16"), "{e}");
    let e = svc.fails(&["sdo", "upload", "--axis", "x", "0x2000:0"]);
    assert!(
        e.contains(
            "drive 0: SDO 0x2000:00 aborted: 0x06020000 Object does not exist in the object \
             dictionary."
        ),
        "{e}"
    );
    let e = svc.fails(&[
        "sdo", "download", "--axis", "x", "0x1000:0", "0", "--type", "u32",
    ]);
    assert!(
        e.contains("0x06010002 Attempt to write a read only object."),
        "{e}"
    );
    let e = svc.fails(&["sdo", "upload", "--drive", "9", "0x1000:0"]);
    assert!(e.contains("no drive at bus position 9"), "{e}");
    let e = svc.fails(&["sdo", "upload", "--axis", "x", "--drive", "0", "0x1000:0"]);
    assert!(e.contains("cannot be used with"), "{e}");
    let e = svc.fails(&["sdo", "upload", "0x1000:0"]);
    assert!(e.contains("--axis") && e.contains("--drive"), "{e}");
    svc.stop();
}

#[test]
fn without_a_service_gantry_sdo_says_so() {
    let socket = std::env::temp_dir().join(format!("gantry-sdo-none-{}.sock", std::process::id()));
    let out = gantry()
        .args(["sdo", "upload", "--axis", "x", "0x6060:0", "--socket"])
        .arg(&socket)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("cannot reach gantry at"), "{e}");
    assert!(e.contains("is `gantry run` running?"), "{e}");
}
