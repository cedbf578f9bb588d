//! `gantry cam load|tables` end to end, through the binary: `gantry run --no-rt` on the
//! example configuration with a `[[cam]]` table, tables listed, loaded from a CSV file
//! (read by the client, sent as points) and replaced, and through the socket's
//! `cam_load` from points and from a file the service reads; each mistake gets a clear
//! message and a failing exit.

mod support;

use support::{chain_riding_through_stalls, riding_through_stalls, Service};

fn cams(file: &str) -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../deploy/cams/").to_string() + file
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

#[test]
fn gantry_cam_loads_and_lists_tables_of_a_running_service() {
    let press = cams("eccentric.toml");
    let mut svc = Service::start_edited(
        "cam-cli",
        |c| format!("{c}\n[[cam]]\nname = \"press\"\nfile = {press:?}\n"),
        |s| s,
    );
    // The configuration's table.
    assert_eq!(
        svc.ok(&["cam", "tables"]).trim(),
        "slot 0 press: 13 points, cubic, periodic, master 0..360, rise 0"
    );
    // A CSV file, read by the client: a new name, the next slot.
    let knife = cams("flying_knife.csv");
    assert_eq!(
        svc.ok(&["cam", "load", "knife", &knife, "--interpolation", "quintic"])
            .trim(),
        "loaded slot 1 knife: 25 points, quintic, not periodic, master 0..600, rise 400"
    );
    // Replaced under its name: same slot, the new flags.
    assert_eq!(
        svc.ok(&["cam", "load", "knife", &knife, "--periodic"])
            .trim(),
        "loaded slot 1 knife: 25 points, cubic, periodic, master 0..600, rise 400"
    );
    let listed: serde_json::Value =
        serde_json::from_str(&svc.ok(&["cam", "tables", "--json"])).unwrap();
    let tables = listed["tables"].as_array().unwrap();
    assert_eq!(tables.len(), 2, "{listed}");
    assert_eq!(tables[1]["name"], "knife");
    assert_eq!(tables[1]["periodic"], true);
    assert_eq!(tables[1]["master_range"], serde_json::json!([0.0, 600.0]));

    // The socket: points, and a file the service reads.
    let r = raw_request(
        &svc.socket,
        r#"{"v":1,"cmd":"cam_load","name":"lift","points":[[0,0],[10,5],[20,0]],"interpolation":"linear"}"#,
    );
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(r["result"]["slot"], 2);
    assert_eq!(r["result"]["points"], 3);
    assert_eq!(r["result"]["interpolation"], "linear");
    let line = serde_json::json!({"v": 1, "cmd": "cam_load", "name": "press", "file": press});
    let r = raw_request(&svc.socket, &line.to_string());
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(r["result"]["slot"], 0);

    // Mistakes.
    let line = serde_json::json!({"v": 1, "cmd": "cam_load", "name": "x", "file": press,
        "points": [[0, 0], [1, 1]]});
    let r = raw_request(&svc.socket, &line.to_string());
    assert_eq!(
        r["error"], "cam_load: give the table's file or its points, one of the two",
        "{r}"
    );
    let r = raw_request(
        &svc.socket,
        r#"{"v":1,"cmd":"cam_load","name":"x","points":[[0,0],[0,1]]}"#,
    );
    assert_eq!(r["ok"], false, "{r}");
    assert!(r["error"].as_str().unwrap().contains("point"), "{r}");
    let e = svc.fails(&["cam", "load", "x", &knife, "--interpolation", "spline"]);
    assert!(
        e.contains("--interpolation \"spline\" is none of linear, cubic, quintic"),
        "{e}"
    );
    let e = svc.fails(&["cam", "load", "x", "/nonexistent/k.csv"]);
    assert!(e.contains("cannot read cam file /nonexistent/k.csv"), "{e}");
    let e = svc.fails(&["cam", "load", "x", &press, "--non-periodic"]);
    assert!(
        e.contains("eccentric.toml") && e.contains("periodic"),
        "{e}"
    );
    let e = svc.fails(&["cam", "load", "x", &knife, "--periodic", "--non-periodic"]);
    assert!(e.contains("cannot be used with"), "{e}");
    // Nothing of that reached the slots.
    let listed: serde_json::Value =
        serde_json::from_str(&svc.ok(&["cam", "tables", "--json"])).unwrap();
    assert_eq!(listed["tables"].as_array().unwrap().len(), 3, "{listed}");
    let (status, out) = svc.terminate();
    assert!(status.success(), "{out}");
}

/// The example with a cam table `press` (50·(1 − cos θ) over 0..360°, periodic) and a
/// virtual rotary master `m` after its axes.
fn with_press_and_master(config: String) -> String {
    let press = cams("eccentric.toml");
    format!(
        "{config}\n[[cam]]\nname = \"press\"\nfile = {press:?}\n\n\
         [[axis]]\nname = \"m\"\ntype = \"virtual\"\nkind = \"rotary\"\nunits = \"deg\"\n\
         modulo = 360.0\nmax = {{ speed = 360.0, acceleration = 3600.0, jerk = 36000.0 }}\n"
    )
}

#[test]
fn gantry_cam_in_and_out_follow_the_table_on_the_drives() {
    let mut svc = Service::start_edited(
        "cam-in-cli",
        |c| with_press_and_master(riding_through_stalls(c)),
        chain_riding_through_stalls,
    );
    for a in ["x", "y", "z", "c", "m"] {
        svc.ok(&["enable", a]);
    }
    svc.ok(&["jog", "m", "--direction", "+", "--speed", "90"]);
    let out = svc.ok(&["cam", "in", "y", "--master", "m", "--table", "press"]);
    assert!(out.contains("y: following"), "{out}");
    // Every drive of the example takes part (the drive invariant judges them all).
    svc.ok(&["gear", "x", "--master", "m", "--ratio", "1:10"]);
    svc.ok(&["gear", "z", "--master", "m", "--ratio", "1:20"]);
    svc.ok(&[
        "cam",
        "in",
        "c",
        "--master",
        "m",
        "--table",
        "press",
        "--relative",
    ]);
    std::thread::sleep(std::time::Duration::from_millis(2500));
    let st = svc.status();
    let axis = |name: &str| support::axis_of(&st, name);
    let (y, m) = (axis("y"), axis("m"));
    assert_eq!(y["sync"]["camming"], true, "{y}");
    assert_eq!(y["sync"]["in_sync"], true, "{y}");
    assert_eq!(y["sync"]["master"], "m", "{y}");
    // On the table: the eccentric's stroke at the master's angle (the table's 13 points
    // are within 0.011 mm of the cosine).
    let theta = m["set_position"].as_f64().unwrap().to_radians();
    let stroke = 50.0 * (1.0 - theta.cos());
    let got = y["set_position"].as_f64().unwrap();
    assert!(
        (got - stroke).abs() < 0.011,
        "y {got} at m {theta} rad: {stroke}"
    );
    // A table in use is not replaced.
    let e = svc.fails(&["cam", "load", "press", &cams("eccentric.toml")]);
    assert!(e.contains("in use by axis"), "{e}");
    // A table that is not there.
    let e = svc.fails(&["cam", "in", "z", "--master", "m", "--table", "nope"]);
    assert!(e.contains("no cam table \"nope\""), "{e}");
    // Cam out: y goes on at its velocity (ContinuousMotion), then everything halts.
    svc.ok(&["cam", "out", "y"]);
    let y = svc.axis("y");
    assert_eq!(y["state"], "ContinuousMotion", "{y}");
    let e = svc.fails(&["cam", "out", "y"]);
    assert!(e.contains("CamOut"), "{e}");
    for a in ["x", "y", "z", "c", "m"] {
        svc.ok(&["halt", a]);
    }
    let (status, out) = svc.terminate();
    assert!(status.success(), "{out}");
    svc.assert_drive_invariant();
}
