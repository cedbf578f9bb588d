//! `gantry run` on CANopen end to end, through the binary: the shipped example
//! `deploy/examples/sim-canopen-4-axes.toml` — four CiA-402 servos simulated as CANopen
//! nodes on the in-memory CAN bus at 1 Mbit/s in the process, on the wall clock
//! (`--no-rt`: no root, no CAN hardware) — driven by the client commands a user types:
//! status (the nodes, their NMT state and heartbeat), enable, set-position, move, `gantry
//! sdo` upload and download (expedited, segmented, an abort) while an axis moves; SIGTERM
//! shuts it down with the nodes pre-operational, and what the drives recorded holds the
//! drive invariant.

use std::time::{Duration, Instant};

use gantry_sim::plant::record::read_records;

mod support;
use support::Service;

#[test]
fn gantry_run_drives_simulated_canopen_nodes_with_status_moves_and_sdo() {
    let mut svc = Service::start_example(
        "canopen",
        "sim-canopen-4-axes.toml",
        "sim-canopen-4-servos.toml",
        |chain| chain,
    );
    // The status names each axis' node, the NMT state its heartbeat reports and how long
    // ago it came against the consumer time.
    // The socket opens before the cycle's first snapshot: wait for a few cycles.
    let end = Instant::now() + Duration::from_secs(10);
    let s = loop {
        let s = svc.status();
        if s["cycles"].as_u64().unwrap_or(0) >= 20 {
            break s;
        }
        assert!(Instant::now() < end, "no cycles: {s}");
        std::thread::sleep(Duration::from_millis(50));
    };
    let drives = s["drives"].as_array().unwrap();
    assert_eq!(drives.len(), 4);
    for (i, d) in drives.iter().enumerate() {
        let n = &d["canopen"];
        assert_eq!(n["node"], i as u64 + 1, "{d}");
        assert_eq!(n["nmt"], "Operational", "{d}");
        assert_eq!(n["heartbeat_limit_ms"], 300, "{d}");
        assert!(n["heartbeat_ms_ago"].as_u64().unwrap() < 300, "{d}");
        assert_eq!(n["lost_tpdos"], 0, "{d}");
    }
    let text = svc.ok(&["status"]);
    assert!(text.contains("NMT (heartbeat)"), "{text}");
    assert!(text.contains("bus: CANopen, TPDO sets lost 0 ("), "{text}");
    for (axis, node) in [("x", 1), ("y", 2), ("z", 3), ("c", 4)] {
        let row = text
            .lines()
            .find(|l| l.starts_with(&format!("{axis:<6} {node:<5} Operational")))
            .unwrap_or_else(|| panic!("no node row for {axis} in\n{text}"));
        assert!(row.contains("(limit 300)"), "{row}");
    }

    // Enable, home, move: the drive follows over RPDOs and SYNC.
    assert!(svc.ok(&["enable", "x"]).contains("x: enabled at"));
    let out = svc.ok(&["set-position", "x", "--position", "0"]);
    assert!(out.contains("x: position set to 0.000"), "{out}");
    let out = svc.ok(&["move", "x", "--to", "20", "--speed", "100"]);
    assert!(out.contains("x: done at 20.0"), "{out}");
    for (axis, to) in [("y", "10"), ("z", "5"), ("c", "90")] {
        assert!(svc.ok(&["enable", axis]).contains("enabled at"));
        svc.ok(&["set-position", axis, "--position", "0"]);
        let out = svc.ok(&["move", axis, "--to", to]);
        assert!(out.contains(&format!("{axis}: done at {to}.0")), "{out}");
    }

    // SDO beside the PDOs: the statusword (expedited, 2 bytes) says Operation enabled;
    // the position actual value is the drive's count for 20 mm (2^17 counts per 5 mm).
    let sw = svc.ok(&["sdo", "upload", "--axis", "x", "0x6041:0", "--type", "u16"]);
    let sw: u16 = sw.trim().parse().unwrap_or_else(|e| panic!("{sw:?}: {e}"));
    assert_eq!(
        sw & 0x006F,
        0x0027,
        "statusword 0x{sw:04X}: Operation enabled"
    );
    let counts = svc.ok(&["sdo", "upload", "--axis", "x", "0x6064:0", "--type", "i32"]);
    let counts: i64 = counts.trim().parse().unwrap();
    assert!((counts - 524_288).abs() <= 20, "{counts} counts at 20 mm");
    // While x moves: a download and an upload of another drive, and a segmented upload
    // (the device name, 24 bytes) of the moving one.
    svc.ok(&["move", "x", "--to", "120", "--speed", "100", "--no-wait"]);
    std::thread::sleep(Duration::from_millis(100));
    svc.ok(&[
        "sdo", "download", "--axis", "c", "0x6065:0", "5000", "--type", "u32",
    ]);
    let window = svc.ok(&["sdo", "upload", "--axis", "c", "0x6065:0", "--type", "u32"]);
    assert_eq!(window.trim(), "5000");
    let name = svc.ok(&[
        "sdo", "upload", "--axis", "x", "0x1008:0", "--type", "string",
    ]);
    assert_eq!(name.trim(), "gantry-sim CiA 402 servo");
    // By node id: node 4 is c's drive, its serial number (0x1018:04) is its node id.
    let serial = svc.ok(&["sdo", "upload", "--node", "4", "0x1018:4", "--type", "u32"]);
    assert_eq!(serial.trim(), "4");
    let e = svc.fails(&["sdo", "upload", "--node", "9", "0x1018:4"]);
    assert!(
        e.contains("--node 9: no such CANopen node on this bus (its nodes: 1, 2, 3, 4)"),
        "{e}"
    );
    let moving = svc.status();
    assert_eq!(moving["axes"][0]["state"], "DiscreteMotion", "{moving}");
    // An object the drive does not have: its abort code and the CiA 301 text.
    let e = svc.fails(&["sdo", "upload", "--axis", "y", "0x2FFF:0"]);
    assert!(
        e.contains("0x06020000 Object does not exist in the object dictionary"),
        "{e}"
    );
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let s = svc.status();
        match s["axes"][0]["state"].as_str() {
            Some("Standstill") => break,
            Some("DiscreteMotion") => {}
            _ => panic!("x stopped on its way: {s}"),
        }
        assert!(Instant::now() < end, "x did not arrive: {s}");
        std::thread::sleep(Duration::from_millis(100));
    }
    let s = svc.status();
    assert!(
        (s["axes"][0]["position"].as_f64().unwrap() - 120.0).abs() < 0.05,
        "{s}"
    );
    for d in s["drives"].as_array().unwrap() {
        assert_eq!(d["canopen"]["lost_tpdos"], 0, "{d}");
        assert!(d["bus_fault"].is_null(), "{d}");
    }

    // SIGTERM: quick stop, disable, the nodes pre-operational, exit 0, the drives'
    // records written and judged.
    let (status, out) = svc.terminate();
    assert!(status.success(), "{out}");
    assert!(out.contains("CANopen: 4 nodes operational"), "{out}");
    assert!(out.contains("CANopen: nodes pre-operational"), "{out}");
    // The nodes no longer watch gantry's SYNC and heartbeat (canopen_shutdown.rs).
    assert!(
        out.contains("heartbeat consumer taken back on node(s) 1, 2, 3, 4 in"),
        "{out}"
    );
    assert!(out.contains("gantry: drive records written to "), "{out}");
    let records = read_records(&svc.dir.join("drive-records.json")).unwrap();
    assert!(
        records.iter().flatten().all(|r| r.targets > 100),
        "every drive took setpoints: {records:?}"
    );
    // The drive invariant; not real time (--no-rt): missed and doubled setpoints are the
    // host's, not judged.
    svc.assert_drive_invariant();
}

/// `gantry sdo` with a file: node 1's recorder 0x2F00 (64 KiB of known content, the
/// chain's `recorder_bytes`) uploaded to a file with `--out`, 64 KiB written to its
/// scratch 0x2F01 from a file with `--file` and read back, every byte checked; a file
/// larger than a transfer carries is refused with its size, and what was typed wrong is
/// said before anything is asked of the service.
#[test]
fn gantry_sdo_moves_64_kib_to_and_from_files() {
    use gantry_sim::canopen::dictionary::recorder_byte;
    const BYTES: usize = 65_536;
    let mut svc = Service::start_example(
        "canopen-sdo-files",
        "sim-canopen-4-axes.toml",
        "sim-canopen-4-servos.toml",
        |chain| {
            chain.replacen(
                "node = 1\n",
                &format!("node = 1\nrecorder_bytes = {BYTES}\nscratch_bytes = {BYTES}\n"),
                1,
            )
        },
    );
    // The socket opens before the cycle's first snapshot: wait for a few cycles.
    let end = Instant::now() + Duration::from_secs(10);
    while svc.status()["cycles"].as_u64().unwrap_or(0) < 20 {
        assert!(Instant::now() < end, "no cycles");
        std::thread::sleep(Duration::from_millis(50));
    }
    // `gantry sdo DIRECTION TARGET… OBJECT FLAG FILE`, its arguments.
    let with_file = |direction: &'static str,
                     target: &[&'static str],
                     object: &'static str,
                     flag: &'static str,
                     file: &std::path::Path| {
        let mut a = vec!["sdo".to_string(), direction.to_string()];
        a.extend(target.iter().map(|t| t.to_string()));
        a.extend([
            object.to_string(),
            flag.to_string(),
            file.display().to_string(),
        ]);
        a
    };
    fn args(a: &[String]) -> Vec<&str> {
        a.iter().map(String::as_str).collect()
    }
    let dir = svc.dir.clone();
    let out = dir.join("recorder.bin");
    let said = svc.ok(&args(&with_file(
        "upload",
        &["--node", "1"],
        "0x2F00:0",
        "--out",
        &out,
    )));
    assert_eq!(said.trim(), format!("{BYTES} bytes to {}", out.display()));
    let got = std::fs::read(&out).unwrap();
    assert_eq!(got.len(), BYTES);
    let first_bad = (0..BYTES).find(|&i| got[i] != recorder_byte(i));
    assert_eq!(first_bad, None, "the recorder's bytes in the file");

    let written: Vec<u8> = (0..BYTES).map(|i| recorder_byte(3 * i + 1)).collect();
    let file = dir.join("parameters.bin");
    std::fs::write(&file, &written).unwrap();
    let mut download = with_file("download", &["--axis", "x"], "0x2F01:0", "--file", &file);
    download.push("--json".into());
    let said = svc.ok(&args(&download));
    let j: serde_json::Value = serde_json::from_str(said.trim()).unwrap();
    assert_eq!(j["bytes"], BYTES as u64, "{j}");
    let back = dir.join("back.bin");
    svc.ok(&args(&with_file(
        "upload",
        &["--axis", "x"],
        "0x2F01:0",
        "--out",
        &back,
    )));
    assert!(std::fs::read(&back).unwrap() == written, "read back");

    let big = dir.join("too-big.bin");
    std::fs::write(&big, vec![0u8; BYTES + 1]).unwrap();
    let e = svc.fails(&args(&with_file(
        "download",
        &["--axis", "x"],
        "0x2F01:0",
        "--file",
        &big,
    )));
    assert!(
        e.contains(
            "drive 0: SDO 0x2F01:00: the object has 65537 bytes, more than the 65536 bytes a \
             transfer carries here (`[bus] sdo_max_bytes`)"
        ),
        "{e}"
    );
    let e = svc.fails(&args(&with_file(
        "download",
        &["--axis", "x"],
        "0x2F01:0",
        "--file",
        std::path::Path::new("/nonexistent/p.bin"),
    )));
    assert!(e.contains("/nonexistent/p.bin"), "{e}");
    let e = svc.fails(&[
        "sdo", "download", "--axis", "x", "0x2F01:0", "01", "--file", "p.bin",
    ]);
    assert!(e.contains("cannot be used with"), "{e}");
    let e = svc.fails(&[
        "sdo", "upload", "--axis", "x", "0x2F01:0", "--type", "u8", "--out", "p.bin",
    ]);
    assert!(e.contains("cannot be used with"), "{e}");
    let (status, out) = svc.terminate();
    assert!(status.success(), "{out}");
}
