//! `gantry run` end to end, through the binary: the service on the example configuration
//! with simulated drives in the process (`--no-rt`: no root needed), driven by the client
//! commands a user types — status, enable, set-position, move (absolute, relative, JSON),
//! jog + halt, stop + release, reset, trace — and by hostile requests on the raw socket;
//! SIGTERM shuts it down gracefully. Without the capabilities it refuses to start.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

mod support;

use support::{example, gantry, Service};

fn raw_request(socket: &Path, line: &[u8]) -> serde_json::Value {
    let mut s = UnixStream::connect(socket).unwrap();
    s.write_all(line).unwrap();
    let mut reply = String::new();
    BufReader::new(s).read_line(&mut reply).unwrap();
    serde_json::from_str(&reply).unwrap()
}

#[test]
fn the_cli_drives_a_running_service_and_sigterm_stops_it_gracefully() {
    let svc = Service::start("e2e");
    let s = svc.status();
    assert_eq!(s["axes"].as_array().unwrap().len(), 4);
    assert_eq!(s["real_time"], false);
    assert!(svc.ok(&["status"]).contains("Disabled"));

    // Off when off is no error; each command says what it did.
    assert!(svc.ok(&["disable", "y"]).contains("y: disabled at"));
    let out = svc.ok(&["reset", "y"]);
    assert!(
        out.contains(", Disabled (its drive's power is off: `gantry enable y`)"),
        "{out}"
    );
    assert!(svc.ok(&["enable", "x"]).contains("x: enabled at"));
    assert_eq!(svc.axis("x")["state"], "Standstill");
    let e = svc.fails(&["move", "x", "--to", "20"]);
    assert!(e.contains("not homed"), "{e}");
    let out = svc.ok(&["set-position", "x", "--position", "0"]);
    assert!(out.contains("x: position set to 0.000"), "{out}");
    // The client refuses what is not a number before sending it.
    let e = svc.fails(&["move", "x", "--to", "nan"]);
    assert!(e.contains("nan is not a finite number"), "{e}");
    let out = svc.ok(&["move", "x", "--to", "20", "--speed", "100"]);
    assert!(out.contains("x: done at 20.0"), "{out}");
    let out = svc.ok(&["move", "x", "--to", "5", "--mode", "relative", "--json"]);
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(j["status"], "Done");
    assert!((j["position"].as_f64().unwrap() - 25.0).abs() < 0.05, "{j}");

    // Jog, then halt.
    let out = svc.ok(&["jog", "x", "--direction", "+", "--speed", "20"]);
    assert!(out.contains("`gantry halt x` stops it"), "{out}");
    std::thread::sleep(Duration::from_millis(300));
    let x = svc.axis("x");
    assert_eq!(
        x["state"],
        "ContinuousMotion",
        "{x}\n{}",
        svc.ok(&["status"])
    );
    assert!(svc.ok(&["halt", "x"]).contains("x: halted at"));
    assert!(svc.axis("x")["position"].as_f64().unwrap() > 25.5);

    // Stop locks the axis until released.
    svc.ok(&["stop", "x"]);
    let e = svc.fails(&["move", "x", "--to", "0"]);
    assert!(e.contains("Stopping"), "{e}");
    svc.ok(&["release", "x"]);

    // Trace while a move runs.
    svc.ok(&["move", "x", "--to", "0", "--no-wait"]);
    let csv = std::env::temp_dir().join(format!("gantry-trace-{}.csv", std::process::id()));
    let out = svc.ok(&[
        "trace",
        "x",
        "--seconds",
        "0.5",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(out.contains("samples of x"), "{out}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(
        lines[0].contains("x.set") && lines[0].contains("x.actual"),
        "{}",
        lines[0]
    );
    assert!(lines.len() > 300, "0.5 s at 1 kHz: {} lines", lines.len());
    std::fs::remove_file(&csv).unwrap();

    // Mistakes get clear answers, and the service goes on.
    let e = svc.fails(&["enable", "w"]);
    assert!(e.contains("no axis named \"w\""), "{e}");
    let e = svc.fails(&["move", "x", "--to", "1", "--speed", "-3"]);
    assert!(e.contains("speed"), "{e}");
    for (line, says) in [
        (&b"garbage\n"[..], "not JSON"),
        (&b"{\"v\":9,\"cmd\":\"status\"}\n"[..], "version 9"),
        (
            &b"{\"v\":1,\"cmd\":\"move\",\"axis\":\"x\",\"to\":1e999}\n"[..],
            "not JSON",
        ),
        (
            &b"{\"v\":1,\"cmd\":\"halt\",\"axis\":\"x\",\"extra\":1}\n"[..],
            "unknown field",
        ),
        // Words of the protocol: the field, the word and the choices.
        (
            &b"{\"v\":1,\"cmd\":\"move\",\"axis\":\"x\",\"to\":1,\"mode\":\"sideways\"}\n"[..],
            "mode \"sideways\" is not one of \"absolute\", \"relative\"",
        ),
        (
            &b"{\"v\":1,\"cmd\":\"jog\",\"axis\":\"x\",\"direction\":\"up\",\"speed\":1}\n"[..],
            "direction \"up\" is not one of \"+\", \"-\"",
        ),
        // x is linear: the way round a modulo axis means nothing there.
        (
            &b"{\"v\":1,\"cmd\":\"move\",\"axis\":\"x\",\"to\":1,\"mode\":\"positive\"}\n"[..],
            "mode \"positive\" is for a modulo axis; x is not one",
        ),
    ] {
        let r = raw_request(&svc.socket, line);
        assert_eq!(r["ok"], false, "{r}");
        assert!(r["error"].as_str().unwrap().contains(says), "{r}");
    }
    // Longer than a request may be: with the example's `sdo_max_bytes` (64 KiB, carried as
    // hex digits) that is more than 128 KiB.
    let max_line = gantry::service::protocol::max_line(
        gantry::config::Config::load(&svc.dir.join("gantry.toml").display().to_string())
            .unwrap()
            .bus
            .sdo_max_bytes(),
    );
    let huge = vec![b'x'; max_line + 1];
    let r = raw_request(&svc.socket, &huge);
    assert!(r["error"].as_str().unwrap().contains("longer than"), "{r}");
    // A reset says what it left the axis in (x has no error: it stays powered).
    let out = svc.ok(&["reset", "x"]);
    assert!(
        out.contains("x: reset at") && out.contains(", Standstill (its drive is powered)"),
        "{out}"
    );
    assert_eq!(svc.status()["ended"], false);

    // Every drive moves, so that the invariant judges all four; the rotary table c across
    // its wrap at 360° both ways (issue 10 §1: its drive was sent a full period's step).
    for a in ["y", "z", "c"] {
        svc.ok(&["enable", a]);
    }
    svc.ok(&["set-position", "c", "--position", "350"]);
    let out = svc.ok(&[
        "move", "c", "--to", "30", "--mode", "relative", "--speed", "360",
    ]);
    assert!(out.contains("c: done at"), "{out}");
    assert!((svc.axis("c")["position"].as_f64().unwrap() - 20.0).abs() < 0.05);
    let out = svc.ok(&[
        "move", "c", "--to", "-40", "--mode", "relative", "--speed", "720",
    ]);
    assert!(out.contains("c: done at"), "{out}");
    assert!((svc.axis("c")["position"].as_f64().unwrap() - 340.0).abs() < 0.05);
    for (a, to) in [("y", "15"), ("z", "-5")] {
        svc.ok(&["set-position", a, "--position", "0"]);
        let out = svc.ok(&["move", a, "--to", to]);
        assert!(out.contains(&format!("{a}: done at")), "{out}");
    }

    // SIGTERM: quick stop, disable, bus to PreOp, exit 0 — and a trace still recording
    // gets what was recorded up to the end, the stop included.
    let mut svc = svc;
    svc.ok(&["move", "x", "--to", "300", "--no-wait"]);
    let csv = std::env::temp_dir().join(format!("gantry-trace-end-{}.csv", std::process::id()));
    let recording = svc
        .command(&["trace", "x", "--seconds", "30"])
        .arg("--out")
        .arg(&csv)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(400));
    let (status, out) = svc.terminate();
    assert!(status.success(), "{out}");
    assert!(out.contains("bus: slaves in PreOp"), "{out}");
    assert!(out.contains("stopped after"), "{out}");
    assert!(!svc.socket.exists(), "the socket is removed");
    // It wrote what its drives saw, and said what it was.
    assert!(out.contains("gantry: drive records written to "), "{out}");
    assert!(
        out.contains("  c: largest target step ") && !out.contains("drive invariant broken"),
        "{out}"
    );
    svc.assert_drive_invariant();
    let recorded = recording.wait_with_output().unwrap();
    let said = String::from_utf8_lossy(&recorded.stdout);
    assert!(
        recorded.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&recorded.stderr)
    );
    assert!(
        said.contains("gantry stopped: the recording ends there"),
        "{said}"
    );
    let lines = std::fs::read_to_string(&csv).unwrap();
    std::fs::remove_file(&csv).unwrap();
    assert!(
        lines.lines().count() > 300,
        "{} lines",
        lines.lines().count()
    );
}

#[test]
fn without_capabilities_it_refuses_to_start_and_says_which() {
    // As nobody (no capabilities, RLIMIT_RTPRIO 0): real time needs CAP_SYS_NICE.
    let out = Command::new("setpriv")
        .args(["--reuid=65534", "--regid=65534", "--clear-groups"])
        .arg(env!("CARGO_BIN_EXE_gantry"))
        .args(["run", "--config"])
        .arg(example("sim-4-axes.toml"))
        .output();
    let Ok(out) = out else {
        panic!("setpriv (util-linux) is needed for this test");
    };
    let e = String::from_utf8_lossy(&out.stderr);
    if nix::unistd::Uid::current().is_root() {
        assert!(!out.status.success());
        assert!(e.contains("needs CAP_SYS_NICE"), "{e}");
        assert!(e.contains("--no-rt"), "{e}");
    } else {
        // Not root: setpriv itself cannot switch users; the test needs root.
        assert!(!out.status.success(), "{e}");
    }
}

#[test]
fn an_axis_on_a_drive_the_bus_does_not_have_stops_start_up() {
    let dir = std::env::temp_dir().join(format!("gantry-missing-drive-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(example("sim-4-axes.toml")).unwrap();
    assert!(text.contains("drive = 3"));
    std::fs::write(dir.join("g.toml"), text.replace("drive = 3", "drive = 7")).unwrap();
    std::fs::copy(example("sim-4-servos.toml"), dir.join("sim-4-servos.toml")).unwrap();
    let out = gantry()
        .args(["run", "--no-rt", "--config"])
        .arg(dir.join("g.toml"))
        .arg("--socket")
        .arg(dir.join("s.sock"))
        .output()
        .unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("axis \"c\" is on drive 7, but the bus has 4 slaves"),
        "{e}"
    );
}

#[test]
fn a_bring_up_error_prints_what_failed_and_its_cause_once() {
    let dir = std::env::temp_dir().join(format!("gantry-bad-pcap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(example("sim-4-axes.toml")).unwrap();
    assert!(text.contains("# pcap = \"gantry.pcap\""));
    let text = text.replace("# pcap = \"gantry.pcap\"", "pcap = \"no-such-dir/g.pcap\"");
    std::fs::write(dir.join("g.toml"), text).unwrap();
    std::fs::copy(example("sim-4-servos.toml"), dir.join("sim-4-servos.toml")).unwrap();
    let out = gantry()
        .args(["run", "--no-rt", "--config"])
        .arg(dir.join("g.toml"))
        .arg("--socket")
        .arg(dir.join("s.sock"))
        .output()
        .unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    // What failed (the link, by its file), then why (the OS), each said once.
    assert!(
        e.contains("gantry: pcap ") && e.contains("no-such-dir/g.pcap: No such file or directory"),
        "{e}"
    );
    assert_eq!(e.matches("No such file").count(), 1, "{e}");
}
