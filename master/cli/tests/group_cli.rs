//! Axis groups through the binary: `gantry run --no-rt` on the example with a `[[group]]`
//! of x and y; `gantry group enable`, a line and an arc (`gantry group line`, `gantry
//! group arc`) end exactly where they were sent, `gantry status` shows the group's state
//! and the axes' coordinated status, refusals name the rule; the simulated drives' records
//! hold the drive invariant (no setpoint jump, no limit exceeded). Moves queued while
//! the group moves (`--buffer`, `--transition`, `--corner-deviation`) end exactly on
//! target, and the status carries each group's corner figures.

mod support;

use std::time::{Duration, Instant};

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

/// Waits (30 s at most) until group `group` is in `state` with its axes' set positions
/// at `at`; the last status.
fn wait_group_at(
    s: &Service,
    group: usize,
    state: &str,
    at: [(&str, f64); 2],
) -> serde_json::Value {
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let st = s.status();
        let there = at
            .iter()
            .all(|&(a, p)| support::axis_of(&st, a)["set_position"].as_f64() == Some(p));
        if st["groups"][group]["state"] == state && there {
            return st;
        }
        assert!(
            Instant::now() < end,
            "the group never stood at {at:?}: {st}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn moves_queued_blended_while_the_group_moves_end_exactly_on_target() {
    let mut s = Service::start_edited(
        "group-blend-cli",
        |c| with_group(riding_through_stalls(c)),
        chain_riding_through_stalls,
    );
    for a in ["x", "y", "z", "c"] {
        s.ok(&["enable", a]);
    }
    for a in ["x", "y"] {
        s.ok(&["set-position", a, "--position", "0"]);
    }
    s.ok(&["group", "enable", "xy"]);
    // The corner figures are there, numbers, from the start.
    let g = &s.status()["groups"][0];
    for field in [
        "blends",
        "last_corner_deviation",
        "max_corner_deviation",
        "last_transit_speed",
    ] {
        assert!(g[field].is_number(), "{field}: {g}");
    }
    assert_eq!(g["blends"], 0, "{g}");
    // A wrong buffer word: the command line names the option and the words.
    let e = s.fails(&[
        "group",
        "line",
        "xy",
        "--to",
        "10,10",
        "--velocity",
        "50",
        "--buffer",
        "blended",
    ]);
    assert!(
        e.contains("--buffer") && e.contains(r#"buffer "blended" is not one of "aborting""#),
        "{e}"
    );
    // A corner deviation that is none: the service names the field.
    for bad in ["0", "-0.5"] {
        let e = s.fails(&[
            "group",
            "line",
            "xy",
            "--to",
            "10,10",
            "--velocity",
            "50",
            "--buffer",
            "blending-next",
            "--transition",
            "corner-superimposed",
            "--corner-deviation",
            bad,
        ]);
        assert!(
            e.contains(&format!(
                "corner_deviation = {bad} must be a finite number > 0"
            )),
            "{bad}: {e}"
        );
    }
    assert_eq!(s.status()["groups"][0]["state"], "GroupStandby");
    // A line, then queued behind it while the group moves: a buffered line, an arc
    // tangent to it, a line tangent to the arc and a right-angled corner, blended with
    // the next move's speed and the corner superimposed within 0.5 mm. Each returns once
    // the cycle has taken it.
    s.ok(&[
        "group",
        "line",
        "xy",
        "--to",
        "60,0",
        "--velocity",
        "50",
        "--no-wait",
    ]);
    s.ok(&[
        "group",
        "line",
        "xy",
        "--to",
        "60,40",
        "--velocity",
        "50",
        "--buffer",
        "buffered",
    ]);
    let blended = [
        "--buffer",
        "blending-next",
        "--transition",
        "corner-superimposed",
        "--corner-deviation",
        "0.5",
    ];
    let arc = [
        "group",
        "arc",
        "xy",
        "--end",
        "40,60",
        "--center",
        "40,40",
        "--velocity",
        "40",
    ];
    s.ok(&[&arc[..], &blended].concat());
    let line = ["group", "line", "xy", "--to", "0,60", "--velocity", "50"];
    s.ok(&[&line[..], &blended].concat());
    let line = ["group", "line", "xy", "--to", "0,30", "--velocity", "50"];
    s.ok(&[&line[..], &blended].concat());
    let st = wait_group_at(&s, 0, "GroupStandby", [("x", 0.0), ("y", 30.0)]);
    let g = &st["groups"][0];
    for field in [
        "blends",
        "last_corner_deviation",
        "max_corner_deviation",
        "last_transit_speed",
    ] {
        assert!(g[field].is_number(), "{field}: {g}");
    }
    // The three junctions after the buffered line were passed in motion, each within the
    // deviation asked for.
    assert_eq!(g["blends"], 3, "{g}");
    // `gantry status` shows the group: its state, its axes, its blends.
    let text = s.ok(&["status"]);
    let row = text
        .lines()
        .find(|l| l.starts_with("xy "))
        .unwrap_or_else(|| panic!("no group row: {text}"));
    let cells: Vec<&str> = row.split_whitespace().collect();
    assert_eq!(&cells[..4], ["xy", "GroupStandby", "x,y", "3"], "{row}");
    assert!(
        g["max_corner_deviation"].as_f64().unwrap() <= 0.5 + 1e-9,
        "{g}"
    );
    assert!(g["last_transit_speed"].as_f64().unwrap() > 0.0, "{g}");
    // MC_GroupHalt: a long line halted on its way stands short of its end, on the line,
    // in GroupStandby (not locked: the next move is taken at once).
    s.ok(&[
        "group",
        "line",
        "xy",
        "--to",
        "0,-300",
        "--velocity",
        "50",
        "--no-wait",
    ]);
    std::thread::sleep(Duration::from_millis(300));
    s.ok(&["group", "halt", "xy"]);
    let end = Instant::now() + Duration::from_secs(30);
    let st = loop {
        let st = s.status();
        let v = support::axis_of(&st, "y")["velocity"].as_f64();
        if st["groups"][0]["state"] == "GroupStandby" && v == Some(0.0) {
            break st;
        }
        assert!(Instant::now() < end, "the halt never ended: {st}");
        std::thread::sleep(Duration::from_millis(50));
    };
    let (x, y) = (
        support::axis_of(&st, "x")["set_position"].as_f64().unwrap(),
        support::axis_of(&st, "y")["set_position"].as_f64().unwrap(),
    );
    assert_eq!(x, 0.0, "on the line");
    assert!(y < 30.0 && y > -300.0, "halted on its way: {y}");
    s.ok(&["group", "line", "xy", "--to", "0,0", "--velocity", "50"]);
    wait_group_at(&s, 0, "GroupStandby", [("x", 0.0), ("y", 0.0)]);
    s.ok(&["group", "disable", "xy"]);
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
