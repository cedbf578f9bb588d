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

mod support;

use support::{gantry, Service};

/// A client command that must succeed: its stdout, trimmed.
fn value(svc: &Service, args: &[&str]) -> String {
    svc.ok(args).trim().to_string()
}

/// One raw line on the socket, its reply.
fn raw_request(socket: &std::path::Path, line: &str) -> serde_json::Value {
    use std::io::{BufRead, Write};
    let mut s = std::os::unix::net::UnixStream::connect(socket).unwrap();
    writeln!(s, "{line}").unwrap();
    let mut reply = String::new();
    std::io::BufReader::new(s).read_line(&mut reply).unwrap();
    serde_json::from_str(&reply).unwrap()
}

/// SIGTERM: the service ends as usual after the transfers (bus to PreOp, exit 0).
fn stop(mut svc: Service) {
    let (status, out) = svc.terminate();
    assert!(status.success(), "{out}");
    assert!(out.contains("bus: slaves in PreOp"), "{out}");
}

#[test]
fn gantry_sdo_reads_and_writes_a_drive_of_a_running_service() {
    // The last drive's firmware answers its mailbox in 40 ms (its `[slave.al]` table is
    // the file's last).
    let svc = Service::start_with("sdo-cli", |servos| servos + "mailbox_ms = 40\n");
    // The simulated servo: CiA 402, device type 0x00020192 (0x1000), CSP (0x6060 = 8).
    assert_eq!(
        value(
            &svc,
            &["sdo", "upload", "--axis", "x", "0x1000:0", "--type", "u32"]
        ),
        0x0002_0192u32.to_string()
    );
    assert_eq!(
        value(&svc, &["sdo", "upload", "--axis", "x", "1000:00"]),
        "92010200",
        "hex by default, as on the wire"
    );
    // Its drive's mode of operation, written and read back; the same drive by its bus
    // position.
    assert_eq!(
        value(
            &svc,
            &["sdo", "upload", "--axis", "x", "0x6060:0", "--type", "i8"]
        ),
        "8"
    );
    assert_eq!(
        value(
            &svc,
            &["sdo", "download", "--axis", "x", "0x6060:0", "8", "--type", "i8"]
        ),
        ""
    );
    assert_eq!(
        value(
            &svc,
            &["sdo", "upload", "--drive", "0", "0x6060:0", "--type", "u8"]
        ),
        "8"
    );
    let j: serde_json::Value = serde_json::from_str(&value(
        &svc,
        &[
            "sdo", "upload", "--axis", "y", "0x1018:0", "--type", "u8", "--json",
        ],
    ))
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
    value(
        &svc,
        &[
            "sdo", "download", "--axis", "z", "0x6065:0", "0x1234", "--type", "u32",
        ],
    );
    assert_eq!(
        value(
            &svc,
            &["sdo", "upload", "--axis", "z", "0x6065:0", "--type", "u32"]
        ),
        "4660"
    );
    assert_eq!(
        value(
            &svc,
            &["sdo", "upload", "--axis", "z", "0x6065:0", "--type", "hex"]
        ),
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
    let e = svc.fails(&["sdo", "upload", "--node", "1", "0x6060:0"]);
    assert!(
        e.contains("--node 1: no such CANopen node on this bus (it is not a CANopen bus: use --axis or --drive)"),
        "{e}"
    );
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
    // A drive slower than the time given it (its firmware answers in 40 ms): the
    // transfer times out and says so; its late answer is passed over by the next one.
    let e = svc.fails(&[
        "sdo",
        "upload",
        "--axis",
        "c",
        "0x1018:1",
        "--timeout",
        "0.01",
    ]);
    assert!(
        e.contains("drive 3: SDO 0x1018:01: no answer within 1"),
        "{e}"
    );
    assert_eq!(
        value(
            &svc,
            &["sdo", "upload", "--axis", "c", "0x6060:0", "--type", "u8"]
        ),
        "8"
    );
    let e = svc.fails(&["sdo", "upload", "--axis", "c", "0x6060:0", "--timeout", "0"]);
    assert!(e.contains("--timeout must be 0.001 to 60 s"), "{e}");

    // What a script may send on the socket, checked there too.
    for (line, says) in [
        (
            r#"{"v":1,"cmd":"sdo","axis":"x","direction":"download","index":24672,"sub":0,"data":"zz"}"#,
            r#"sdo: data "zz" is not hex bytes"#,
        ),
        (
            r#"{"v":1,"cmd":"sdo","axis":"x","drive":0,"direction":"upload","index":4096,"sub":0}"#,
            "sdo: name the drive by its axis or by its bus position, one of the two",
        ),
        (
            r#"{"v":1,"cmd":"sdo","drive":0,"direction":"download","index":24672,"sub":0}"#,
            "sdo: a download needs data",
        ),
        (
            r#"{"v":1,"cmd":"sdo","drive":0,"direction":"upload","index":65536,"sub":0}"#,
            "invalid request",
        ),
    ] {
        let reply = raw_request(&svc.socket, line);
        assert_eq!(reply["ok"], false, "{line}");
        let e = reply["error"].as_str().unwrap();
        assert!(e.contains(says), "{line}: {e}");
    }
    stop(svc);
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
