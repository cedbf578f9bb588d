//! Axis groups through the binary: `gantry run --no-rt` on the example with a `[[group]]`
//! of x and y; `gantry group enable`, a line and an arc (`gantry group line`, `gantry
//! group arc`) end exactly where they were sent, `gantry status` shows the group's state
//! and the axes' coordinated status, refusals name the rule; the simulated drives' records
//! hold the drive invariant (no setpoint jump, no limit exceeded).

mod support;

use support::{chain_riding_through_stalls, riding_through_stalls, Service};

fn with_group(config: String) -> String {
    format!("{config}\n[[group]]\nname = \"xy\"\naxes = [\"x\", \"y\"]\n")
}

#[test]
fn a_group_moves_its_axes_along_a_line_and_an_arc() {
    let mut s = Service::start_edited(
        "group-cli",
        |c| with_group(riding_through_stalls(c)),
        chain_riding_through_stalls,
    );
    // A move needs homed axes (seed 004: error 5466): refused, naming the axis.
    for a in ["x", "y", "z", "c"] {
        s.ok(&["enable", a]);
    }
    s.ok(&["group", "enable", "xy"]);
    let st = s.status();
    assert_eq!(st["groups"][0]["name"], "xy", "{st}");
    assert_eq!(st["groups"][0]["state"], "GroupStandby", "{st}");
    assert_eq!(support::axis_of(&st, "x")["coordinated"], true);
    let e = s.fails(&["group", "line", "xy", "--to", "10,20", "--velocity", "50"]);
    assert!(e.contains("not homed") || e.contains("home"), "{e}");
    for a in ["x", "y"] {
        s.ok(&["set-position", a, "--position", "0"]);
    }
    s.ok(&["group", "line", "xy", "--to", "40,30", "--velocity", "50"]);
    let (x, y) = (s.axis("x"), s.axis("y"));
    assert_eq!(x["set_position"].as_f64().unwrap(), 40.0, "{x}");
    assert_eq!(y["set_position"].as_f64().unwrap(), 30.0, "{y}");
    // A half circle around (40, 40) to (40, 50), counter-clockwise.
    s.ok(&[
        "group",
        "arc",
        "xy",
        "--end",
        "40,50",
        "--center",
        "40,40",
        "--velocity",
        "40",
    ]);
    let (x, y) = (s.axis("x"), s.axis("y"));
    assert!(
        (x["set_position"].as_f64().unwrap() - 40.0).abs() < 1e-9,
        "{x}"
    );
    assert!(
        (y["set_position"].as_f64().unwrap() - 50.0).abs() < 1e-9,
        "{y}"
    );
    assert_eq!(s.status()["groups"][0]["state"], "GroupStandby");
    // Refusals: the radius rule (5 is less than half the 40 between start and end), a
    // group the configuration does not have.
    let e = s.fails(&[
        "group",
        "arc",
        "xy",
        "--end",
        "80,50",
        "--radius",
        "5",
        "--velocity",
        "40",
    ]);
    assert!(e.contains("radius"), "{e}");
    let e = s.fails(&["group", "enable", "nope"]);
    assert!(e.contains("no group \"nope\""), "{e}");
    // The XY plot of the path while the group moves back along a line.
    s.ok(&[
        "group",
        "line",
        "xy",
        "--to",
        "0,0",
        "--velocity",
        "30",
        "--no-wait",
    ]);
    let svg = s.dir.join("path.svg");
    let out = s.ok(&[
        "trace",
        "--xy",
        "x",
        "y",
        "--seconds",
        "1",
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert!(out.contains("samples of x, y"), "{out}");
    let doc = std::fs::read_to_string(&svg).unwrap();
    assert!(doc.contains("x / y: set and actual path"), "{doc}");
    assert!(doc.contains("x.set / y.set") && doc.contains("x.actual / y.actual"));
    let longest = doc
        .split("points=\"")
        .skip(1)
        .map(|p| p.split('"').next().unwrap().split(' ').count())
        .max()
        .unwrap();
    assert!(longest > 100, "{longest} points");
    std::thread::sleep(std::time::Duration::from_millis(2500));
    s.ok(&["group", "disable", "xy"]);
    assert_eq!(s.status()["groups"][0]["state"], "GroupDisabled");
    // z and c take part too (the drive invariant judges every drive).
    for a in ["z", "c"] {
        s.ok(&["set-position", a, "--position", "0"]);
    }
    s.ok(&["move", "z", "--to", "5", "--speed", "20"]);
    s.ok(&["move", "c", "--to", "90", "--speed", "90"]);
    let (status, _) = s.terminate();
    assert!(status.success());
    s.assert_drive_invariant();
}
