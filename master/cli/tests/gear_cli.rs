//! Gearing through the binary: `gantry run --no-rt` on the example with a virtual master
//! `m` added; `gantry jog m` moves it, `gantry gear x/y --master m --ratio …` gears two
//! servo axes to it, `gantry status` shows them in gear with the master's name, the set
//! positions keep the ratio, `gantry gear --out` leaves them moving on, refusals come back
//! as the command's error naming the axes; what the simulated drives recorded holds the
//! drive invariant (no setpoint jump, no limit exceeded) all along.

mod support;

use std::time::Duration;

use support::{chain_riding_through_stalls, riding_through_stalls, Service};

/// The example with a virtual master `m` after its axes.
fn with_master(config: String) -> String {
    format!(
        "{config}\n[[axis]]\nname = \"m\"\ntype = \"virtual\"\n\
         max = {{ speed = 100.0, acceleration = 500.0, jerk = 10000.0 }}\n"
    )
}

fn set(axis: &serde_json::Value) -> f64 {
    axis["set_position"].as_f64().unwrap()
}

#[test]
fn gear_two_servo_axes_to_a_virtual_master() {
    let mut s = Service::start_edited(
        "gear-cli",
        |c| with_master(riding_through_stalls(c)),
        chain_riding_through_stalls,
    );
    for a in ["x", "y", "z", "c", "m"] {
        s.ok(&["enable", a]);
    }
    s.ok(&["jog", "m", "--direction", "+", "--speed", "40"]);
    let out = s.ok(&["gear", "x", "--master", "m", "--ratio", "1:2"]);
    assert!(out.contains("x: following"), "{out}");
    s.ok(&[
        "gear",
        "y",
        "--master",
        "m",
        "--ratio",
        "-1",
        "--acceleration",
        "500",
    ]);
    // z and c too (every drive of the example takes part): c turns 3° per mm of m.
    s.ok(&["gear", "z", "--master", "m", "--ratio", "1:4"]);
    s.ok(&["gear", "c", "--master", "m", "--ratio", "3"]);
    std::thread::sleep(Duration::from_millis(1500));
    let st = s.status();
    let axis = support::axis_of;
    for (name, v) in [("x", 20.0), ("y", -40.0)] {
        let a = axis(&st, name);
        assert_eq!(a["state"], "SynchronizedMotion", "{a}");
        assert_eq!(a["sync"]["master"], "m", "{a}");
        assert_eq!(a["sync"]["gearing"], true, "{a}");
        assert_eq!(a["sync"]["in_sync"], true, "{a}");
        assert!((a["velocity"].as_f64().unwrap() - v).abs() < 1e-6, "{a}");
    }
    let table = s.ok(&["status"]);
    let x_row = table.lines().find(|l| l.starts_with("x ")).unwrap();
    assert!(x_row.contains("gear m in sync"), "{table}");
    // The ratio between two snapshots, each consistent in itself.
    std::thread::sleep(Duration::from_millis(500));
    let later = s.status();
    let dm = set(&axis(&later, "m")) - set(&axis(&st, "m"));
    let dx = set(&axis(&later, "x")) - set(&axis(&st, "x"));
    let dy = set(&axis(&later, "y")) - set(&axis(&st, "y"));
    assert!(dm > 5.0, "the master moved {dm}");
    assert!((dx - 0.5 * dm).abs() < 1e-6, "x {dx} for m {dm}");
    assert!((dy + dm).abs() < 1e-6, "y {dy} for m {dm}");

    // Refusals: the command's error, with the axes named.
    let e = s.fails(&["gear", "z", "--master", "z", "--ratio", "1"]);
    assert!(e.contains("cannot follow itself"), "{e}");
    assert_eq!(
        s.axis("z")["sync"]["master"],
        "m",
        "a refused gear changes nothing"
    );
    let e = s.fails(&["gear", "m", "--master", "x", "--ratio", "1"]);
    assert!(e.contains("axis 0 (x)") && e.contains("loop"), "{e}");
    let e = s.fails(&["gear", "z", "--master", "nobody", "--ratio", "1"]);
    assert!(e.contains("nobody"), "{e}");
    let e = s.fails(&["gear", "z", "--master", "m", "--ratio", "1:0"]);
    assert!(e.contains("must not be 0"), "{e}");
    // A virtual axis has no drive: what needs one says so.
    let e = s.fails(&["sdo", "upload", "--axis", "m", "0x6041:0", "--type", "u16"]);
    assert!(
        e.contains("m is a virtual axis: it has no drive for an SDO transfer"),
        "{e}"
    );
    let e = s.fails(&["home", "m", "--drive"]);
    assert!(e.contains("m is a virtual axis: it has no drive"), "{e}");
    let e = s.fails(&["commission", "m", "commutation"]);
    assert!(e.contains("m is a virtual axis: it has no drive"), "{e}");
    let e = s.fails(&["gear", "m", "--out"]);
    assert!(e.contains("GearOut"), "{e}");

    // Gear out: x goes on at its velocity; halt it and the rest.
    s.ok(&["gear", "x", "--out"]);
    let x = s.axis("x");
    assert_eq!(x["state"], "ContinuousMotion", "{x}");
    assert!((x["velocity"].as_f64().unwrap() - 20.0).abs() < 1e-6, "{x}");
    assert_eq!(x["sync"], serde_json::Value::Null, "{x}");
    for a in ["x", "y", "z", "c", "m"] {
        s.ok(&["halt", a]);
    }
    let (status, _) = s.terminate();
    assert!(status.success());
    s.assert_drive_invariant();
}
