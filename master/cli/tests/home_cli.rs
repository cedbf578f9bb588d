//! `gantry home` end to end, through the binary: `gantry run --no-rt` on the example
//! configuration with axis `x`'s limit and reference switches wired to its drive (the
//! simulated servo's switch cams, its 0x60FD and touch probe), homed from the shell with
//! the phases shown; the reference lands on the home switch's edge to the count (the
//! simulated drive's own position, recorded at exit); a wrong parameter gets a clear
//! message and a failing exit.

mod support;

use support::Service;

/// Counts per mm of the example's `x`: 2¹⁷ counts per revolution, 5 mm lead.
const COUNTS_PER_MM: f64 = 131_072.0 / 5.0;
/// The home cam of the first servo (counts): 10 mm to just under 12 mm.
const CAM: (i64, i64) = (262_144, 314_572);

#[test]
fn gantry_home_homes_an_axis_on_its_switch_edge_from_the_shell() {
    let svc = Service::start_edited(
        "home",
        |config| {
            let x = "pdo = \"csp\"                   # mapped by SDO in PreOp: + velocity, torque, error code";
            assert!(config.contains(x), "the example maps x with csp");
            config.replacen(
                x,
                "pdo = \"csp-minimal\"\nswitches = { negative_limit = \"drive\", \
                 positive_limit = \"drive\", reference = \"drive\" }",
                1,
            )
        },
        |chain| {
            let first = "[[slave]]\nkind = \"servo\"\n";
            assert!(chain.contains(first));
            // Homing is this test's claim, not the host's timing: without real time
            // (`--no-rt`) a loaded host stalls the cycle for milliseconds now and then,
            // so the drives ride through far more missed periods than the example's ten.
            let chain = chain.replace("sync_error_limit = 32", "sync_error_limit = 1000");
            chain.replacen(
                first,
                &format!(
                    "{first}[slave.switches]\nnegative_limit = [-9000000000, -1310720]\n\
                     positive_limit = [13107200, 9000000000]\nhome = [{}, {}]\n",
                    CAM.0, CAM.1
                ),
                1,
            )
        },
    );
    svc.ok(&["enable", "x"]);
    // A wrong parameter: refused with the operand named, the axis untouched.
    let e = svc.fails(&["home", "x", "--speed-switch=-5"]);
    assert!(
        e.contains("x:") && e.to_lowercase().contains("speed"),
        "{e}"
    );
    let out = svc.ok(&[
        "home",
        "x",
        "--direction",
        "+",
        "--switches",
        "ref-and-limit",
        "--mode",
        "edge-2",
        "--speed-switch",
        "20",
        "--speed-reference",
        "2",
        "--max-distance-switch",
        "100",
        "--max-distance-reference",
        "20",
        "--reference-offset",
        "0",
        "--normal-position",
        "0",
    ]);
    assert!(out.contains("x: homed; stands at 0.000"), "{out}");
    let x = svc.axis("x");
    assert_eq!(x["homed"], true, "{x}");
    assert_eq!(x["homing"]["reference_set"], true, "{x}");
    // The set position is the reference; the actual, sampled whenever `status` asks,
    // stands on the edge within the drive's standstill hold (its position loop holds
    // the load within a few counts against friction; the lockstep tests, which sample
    // it settled, see the edge to ±1 count).
    assert_eq!(x["set_position"], 0.0, "{x}");
    let p = x["position"].as_f64().unwrap();
    assert!(p.abs() <= 4.0 / COUNTS_PER_MM, "{x}");
    // The reference switch as status shows it: on the cam 1 mm past the edge, off 5 mm
    // before it.
    svc.ok(&["move", "x", "--to", "1", "--speed", "20"]);
    assert_eq!(svc.axis("x")["switches"]["reference"], true);
    let table = svc.ok(&["status"]);
    assert!(
        table
            .lines()
            .any(|l| l.starts_with("x ") && l.contains(" ref ")),
        "{table}"
    );
    svc.ok(&["move", "x", "--to=-5", "--speed", "20"]);
    assert_eq!(svc.axis("x")["switches"]["reference"], false);
    // Left-out parameters keep the last ones: the same run again.
    let out = svc.ok(&["home", "x"]);
    assert!(out.contains("x: homed; stands at 0.000"), "{out}");
}
