//! Cam files: CSV and TOML parsing with their errors (file and line), the extension
//! choosing the format, JSON points, and the two examples in `deploy/cams/`.

use std::path::{Path, PathBuf};

use gantry_kernel::cam::{CamError, Interpolation};

use super::*;
use crate::error_chain::Chain;

fn csv(text: &str) -> Result<CamTable, CamFileError> {
    csv::parse(Path::new("t.csv"), text, None, None)
}

fn toml(text: &str) -> Result<CamTable, CamFileError> {
    toml_format::parse(Path::new("t.toml"), text, None, None)
}

fn message(e: &CamFileError) -> String {
    Chain(e).to_string()
}

#[test]
fn csv_with_header_comments_and_blank_lines() {
    let text = "# a cam\n\nmaster , slave\n0,0\n  # comment\n10, 5 # inline\n20,0\r\n\n";
    let t = csv::parse(
        Path::new("t.csv"),
        text,
        Some(Interpolation::Linear),
        Some(true),
    )
    .unwrap();
    let got: Vec<(f64, f64)> = t.points().iter().map(|p| (p.master, p.slave)).collect();
    assert_eq!(got, [(0.0, 0.0), (10.0, 5.0), (20.0, 0.0)]);
    assert_eq!(t.interpolation(), Interpolation::Linear);
    assert!(t.is_periodic());
    // The caller's defaults: cubic, not periodic; no header needed.
    let t = csv("0,0\n1,1\n2,0\n").unwrap();
    assert_eq!(t.interpolation(), Interpolation::Cubic);
    assert!(!t.is_periodic());
}

#[test]
fn csv_bad_number_names_its_line_and_column() {
    let e = csv("master,slave\n0,0\n# note\n1,1\n2,x1\n").unwrap_err();
    assert!(matches!(
        &e,
        CamFileError::CsvNotANumber { line: 5, column: "slave", text, .. } if text == "x1"
    ));
    assert_eq!(message(&e), "t.csv:5: slave \"x1\" is not a number");
    // Only the first line may be a header.
    let e = csv("master,slave\n0,0\nm,s\n").unwrap_err();
    assert_eq!(message(&e), "t.csv:3: master \"m\" is not a number");
}

#[test]
fn csv_wrong_column_count_names_its_line() {
    let e = csv("0,0\n1,1,1\n").unwrap_err();
    assert!(matches!(
        e,
        CamFileError::CsvColumns {
            line: 2,
            found: 3,
            ..
        }
    ));
    assert_eq!(
        message(&e),
        "t.csv:2: expected 2 columns (master,slave), found 3"
    );
    let e = csv("0,0\n\n1\n").unwrap_err();
    assert_eq!(
        message(&e),
        "t.csv:3: expected 2 columns (master,slave), found 1"
    );
}

#[test]
fn csv_unsorted_master_names_the_points_and_their_lines() {
    let e = csv("master,slave\n0,0\n5,1\n# dip\n4,2\n").unwrap_err();
    match &e {
        CamFileError::Table {
            path: Some(p),
            lines,
            source: CamError::NotIncreasing { index: 2, .. },
        } => {
            assert_eq!(p, &PathBuf::from("t.csv"));
            assert_eq!(lines, &[3, 5]);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(
        message(&e),
        "t.csv: lines 3 and 5: not a usable cam table: cam points 1 and 2: master \
         positions must strictly increase, got 5 then 4"
    );
}

#[test]
fn csv_non_finite_and_too_few_points() {
    let e = csv("0,0\n1,inf\n").unwrap_err();
    assert!(message(&e).starts_with("t.csv:2: not a usable cam table: cam point 1"));
    let e = csv("# only a header\nmaster,slave\n3,4\n").unwrap_err();
    assert_eq!(
        message(&e),
        "t.csv: not a usable cam table: a cam table needs at least 2 points, got 1"
    );
}

#[test]
fn toml_good_with_defaults_and_integers() {
    let t = toml("periodic = true\npoints = [[0.0, 0.0], [90, 10], [180.0, 0.0]]\n").unwrap();
    assert_eq!(t.interpolation(), Interpolation::Cubic);
    assert!(t.is_periodic());
    assert_eq!(t.eval(90.0).slave, 10.0);
    let t = toml("interpolation = \"poly5\"\npoints = [[0, 0], [1, 1]]").unwrap();
    assert_eq!(t.interpolation(), Interpolation::Quintic);
    assert!(!t.is_periodic());
}

#[test]
fn toml_errors_name_the_line() {
    let cases = [
        (
            "points = [[0, 0], [1, 1]]\nspeed = 3\n",
            "t.toml:2: unknown field `speed`",
        ),
        (
            "interpolation = \"cubic\"\n",
            "t.toml:1: missing field `points`",
        ),
        (
            "points = [\n  [0, 0],\n  [1, 1, 2],\n]\n",
            "t.toml:3: points[1] has 3 numbers, expected [master, slave]",
        ),
        (
            "points = [[0, 0], [1]]\n",
            "t.toml:1: points[1] has 1 numbers, expected [master, slave]",
        ),
        (
            "points = [[0, 0], [1, \"a\"]]\n",
            "t.toml:1: invalid type: string \"a\", expected f64",
        ),
        (
            "\ninterpolation = \"spline\"\npoints = [[0, 0], [1, 1]]\n",
            "t.toml:2: interpolation \"spline\" is not one of linear, cubic, quintic \
             (5th-order, poly5)",
        ),
        (
            "points = [\n  [0, 0],\n  [2, 1],\n  [2, 3],\n]\n",
            "t.toml: lines 3 and 4: not a usable cam table: cam points 1 and 2: master \
             positions must strictly increase, got 2 then 2",
        ),
        (
            "periodic = true\ninterpolation = \"quintic\"\npoints = [[0, 0], [1, 1]]\n",
            "t.toml: not a usable cam table: a periodic quintic cam table needs at least 3 \
             points, got 2",
        ),
        ("points = [[0, 0], [1, 1]", "t.toml:1: "),
    ];
    for (text, want) in cases {
        let got = match toml(text) {
            Err(e) => message(&e),
            Ok(t) => panic!("{text:?} accepted: {t:?}"),
        };
        assert!(
            got.starts_with(want),
            "{text:?}: got {got:?}, want {want:?}"
        );
    }
}

#[test]
fn toml_and_caller_must_agree_where_both_speak() {
    let text = "interpolation = \"linear\"\nperiodic = false\npoints = [[0, 0], [1, 1], [2, 0]]";
    let path = Path::new("t.toml");
    let ok = toml_format::parse(path, text, Some(Interpolation::Linear), Some(false)).unwrap();
    assert_eq!(ok.interpolation(), Interpolation::Linear);
    let e = toml_format::parse(path, text, Some(Interpolation::Cubic), None).unwrap_err();
    assert_eq!(
        message(&e),
        "t.toml:1: interpolation = linear in the cam file, but cubic where the file is named"
    );
    let e = toml_format::parse(path, text, None, Some(true)).unwrap_err();
    assert_eq!(
        message(&e),
        "t.toml:2: periodic = false in the cam file, but true where the file is named"
    );
    // Where the file is silent, the caller's values are used.
    let t =
        toml_format::parse(path, "points = [[0, 0], [1, 1], [2, 0]]", None, Some(true)).unwrap();
    assert!(t.is_periodic());
}

#[test]
fn unknown_extension_and_missing_file() {
    for name in ["cam.json", "cam", "cam.csv.bak"] {
        let e = load_cam_file(Path::new(name), None, None).unwrap_err();
        assert!(matches!(e, CamFileError::UnknownExtension { .. }), "{name}");
        assert_eq!(
            message(&e),
            format!("cam file {name}: unknown format (the extension must be .csv or .toml)")
        );
    }
    let e = load_cam_file(Path::new("/nonexistent/gantry/cam.CSV"), None, None).unwrap_err();
    assert!(matches!(e, CamFileError::Read { .. }));
    assert!(message(&e).starts_with("cannot read cam file /nonexistent/gantry/cam.CSV: "));
}

#[test]
fn json_points() {
    let t = cam_from_points(&[[0.0, 0.0], [1.0, 2.0]], Some(Interpolation::Linear), None).unwrap();
    assert_eq!(t.eval(0.5).slave, 1.0);
    let e = cam_from_points(&[[0.0, 0.0], [1.0, 2.0], [1.0, 3.0]], None, None).unwrap_err();
    assert_eq!(
        message(&e),
        "cam points: not a usable cam table: cam points 1 and 2: master positions must \
         strictly increase, got 1 then 1"
    );
}

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../deploy/cams")
        .join(name)
}

#[test]
fn the_example_flying_knife_is_at_web_speed_through_the_cut() {
    let path = example("flying_knife.csv");
    let t = load_cam_file(&path, Some(Interpolation::Quintic), Some(false)).unwrap();
    assert_eq!(t.master_range(), (0.0, 600.0));
    assert_eq!(t.slave_rise(), 400.0);
    // At rest at both ends (the end parabolas are the exact x²/400).
    let (start, end) = (t.eval(0.0), t.eval(600.0));
    assert!(
        start.d1.abs() < 1e-12 && end.d1.abs() < 1e-12,
        "{start:?} {end:?}"
    );
    // Synchronous in the cut zone: d1 = 1, d2 = 0 from 225 to 375 (the points on either
    // side are on the same line).
    for x in [225.0, 260.0, 300.0, 375.0] {
        let s = t.eval(x);
        assert!((s.slave - (x - 100.0)).abs() < 1e-9, "{x}: {s:?}");
        assert!((s.d1 - 1.0).abs() < 1e-9 && s.d2.abs() < 1e-9, "{x}: {s:?}");
    }
    // 1.3 % over web speed just after 200 and before 400, where the designed curve's d2
    // jumps (1/200 to 0): the parabola estimates at those points smooth the jump, and the
    // quintic overshoots a little. max_d1 reports it, so a follower can be checked.
    assert!(t.max_d1() > 1.0 && t.max_d1() < 1.02, "{}", t.max_d1());
}

#[test]
fn the_example_eccentric_follows_the_cosine() {
    let path = example("eccentric.toml");
    let t = load_cam_file(&path, None, None).unwrap();
    assert_eq!(t.interpolation(), Interpolation::Cubic);
    assert!(t.is_periodic());
    assert_eq!((t.master_range(), t.slave_rise()), ((0.0, 360.0), 0.0));
    assert_eq!(t.eval(180.0).slave, 100.0);
    let mut worst = 0.0_f64;
    for k in 0..=3600 {
        let x = k as f64 / 10.0;
        worst = worst.max((t.eval(x).slave - 50.0 * (1.0 - x.to_radians().cos())).abs());
    }
    // The file says within 0.011 mm (measured 0.0101).
    assert!(worst < 0.02, "{worst}");
    println!("eccentric: largest error vs the cosine {worst:.2e} mm");
    let d1 = 50.0 * std::f64::consts::PI / 180.0;
    assert!(
        (t.max_d1() - d1).abs() < 1e-2 * d1,
        "{} vs {d1}",
        t.max_d1()
    );
}
