//! `gantry home` end to end, through the binary: `gantry run --no-rt` on the example
//! configuration with axis `x`'s limit and reference switches wired to its drive (the
//! simulated servo's switch cams, its 0x60FD and touch probe), homed from the shell with
//! the phases shown — by MoveHome and by step-to-absolute-switch, reversing at the limit
//! switch —; the reference lands on the home switch's edge to the count (the simulated
//! drive's own position, recorded at exit); a wrong parameter gets a clear message and a
//! failing exit.

mod support;

use support::Service;

/// Counts per mm of the example's `x`: 2¹⁷ counts per revolution, 5 mm lead.
const COUNTS_PER_MM: f64 = 131_072.0 / 5.0;
/// The home cam of the first servo (counts): 10 mm to just under 12 mm.
const CAM: (i64, i64) = (262_144, 314_572);
/// The first servo's negative limit switch: below −50 mm (counts).
const NEGATIVE_LIMIT: i64 = -1_310_720;

/// One service at a time: each runs a cycle and a simulator on this host's two CPUs, and
/// two at once make each other's cycles late.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The example with `x`'s switches on its drive, and the first servo's cams: the home cam
/// at [`CAM`], the limit switches below −50 mm and above 500 mm; `edit` changes the
/// configuration further.
fn start(
    tag: &str,
    edit: impl FnOnce(String) -> String,
) -> (Service, std::sync::MutexGuard<'static, ()>) {
    let one = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
    let svc = Service::start_edited(
        tag,
        |config| {
            let x = "pdo = \"csp\"                   # mapped by SDO in PreOp: + velocity, torque, error code";
            assert!(config.contains(x), "the example maps x with csp");
            edit(config.replacen(
                x,
                "pdo = \"csp-minimal\"\nswitches = { negative_limit = \"drive\", \
                 positive_limit = \"drive\", reference = \"drive\" }",
                1,
            ))
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
                    "{first}[slave.switches]\nnegative_limit = [-9000000000, {NEGATIVE_LIMIT}]\n\
                     positive_limit = [13107200, 9000000000]\nhome = [{}, {}]\n",
                    CAM.0, CAM.1
                ),
                1,
            )
        },
    );
    (svc, one)
}

#[test]
fn gantry_home_homes_an_axis_on_its_switch_edge_from_the_shell() {
    let (svc, _one) = start("home", |c| c);
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

/// Beckhoff step-to-absolute-switch from the shell: started below the cam moving
/// negative, the run reverses at the negative limit switch and ends on the cam's negative
/// edge moving positive (`edge-switch-positive`); that edge gets `--set-position` to the
/// count, read back from the position offset against the simulated cam and by the
/// reference switch itself. `gantry home x` alone repeats it. Refusals name what is wrong.
#[test]
fn gantry_home_step_to_switch_reverses_at_the_limit_and_sets_the_cam_edge() {
    // Several runs and moves, some 20 s: what is homed is this test's claim, not the
    // host's timing. Without real time (`--no-rt`) on a loaded host the 1 ms cycle
    // overruns ten times in a row now and then and the axes stop (seen here at a load of
    // 4 on 2 CPUs): a 4 ms cycle, and a thousand overruns, lost frames or wrong working
    // counters in a row before the stop (as `persist_cli.rs`).
    // The run of this test: below the cam moving negative, ended by the cam's negative
    // edge; `more` options after it.
    let run = |more: &[&'static str]| {
        let mut args = vec![
            "home",
            "x",
            "--step-to-switch",
            "--direction",
            "negative",
            "--switch-mode",
            "edge-switch-positive",
        ];
        args.extend_from_slice(more);
        args
    };
    let (svc, _one) = start("home-step", |c| {
        let mut c = c;
        for (from, to) in [
            ("overrun_limit = 10 ", "overrun_limit = 1000 "),
            ("cycle_us = 1000 ", "cycle_us = 4000 "),
            ("lost_frames_limit = 3 ", "lost_frames_limit = 1000 "),
            (
                "working_counter_limit = 3 ",
                "working_counter_limit = 1000 ",
            ),
        ] {
            assert!(c.contains(from), "the example has {from:?}");
            c = c.replacen(from, to, 1);
        }
        c
    });
    svc.ok(&["enable", "x"]);
    // Nothing saved: the first call names direction, switch mode and velocity.
    let e = svc.fails(&["home", "x", "--step-to-switch", "--velocity", "40"]);
    assert!(
        e.contains("no direction given, and axis \"x\" has none saved")
            && e.contains("names direction, switch mode and velocity"),
        "{e}"
    );
    // Out of range: refused by the axis with the parameter named, nothing saved.
    let e = svc.fails(&run(&["--velocity", "5000"]));
    assert!(
        e.contains("StepAbsoluteSwitch: parameter Velocity = 5000 exceeds the axis maximum"),
        "{e}"
    );
    let e = svc.fails(&run(&["--velocity", "40", "--deceleration=-400"]));
    assert!(
        e.contains("StepAbsoluteSwitch: parameter Deceleration = -400 must be > 0"),
        "{e}"
    );
    let e = svc.fails(&["home", "x", "--step-to-switch", "--switch-mode", "on"]);
    assert!(
        e.contains("no direction given"),
        "refused calls saved nothing: {e}"
    );
    assert_eq!(svc.axis("x")["state"], "Standstill");
    assert_eq!(svc.axis("x")["homed"], false);

    // Not homed, the axis position is the drive's (offset 0): below the cam.
    let x = svc.axis("x");
    assert_eq!(x["position_offset"], 0.0, "{x}");
    let from = x["position"].as_f64().unwrap();
    assert!(
        from < CAM.0 as f64 / COUNTS_PER_MM,
        "starts below the cam: {from}"
    );
    let mut home = svc
        .command(&run(&[
            "--velocity",
            "40",
            "--deceleration",
            "400",
            "--set-position",
            "100",
        ]))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Where the run goes, sampled while it runs (the offset stays 0 until it sets the
    // edge's position): down towards the negative limit switch before it turns.
    let mut lowest = f64::INFINITY;
    let mut samples = 0;
    while home.try_wait().unwrap().is_none() {
        let x = svc.axis("x");
        if x["homing"]["reference_found"] == true {
            break;
        }
        lowest = lowest.min(x["position"].as_f64().unwrap());
        samples += 1;
    }
    let done = home.wait_with_output().unwrap();
    let out = String::from_utf8_lossy(&done.stdout);
    let err = String::from_utf8_lossy(&done.stderr);
    assert!(done.status.success(), "{out}{err}");
    assert!(
        out.contains("x: homed by step-to-switch; stands at 10"),
        "{out}"
    );
    let limit = NEGATIVE_LIMIT as f64 / COUNTS_PER_MM;
    eprintln!("the run went down to {lowest} mm ({samples} samples; the limit at {limit})");
    assert!(
        lowest < limit + 5.0,
        "went down to {lowest} only ({samples} samples; the limit switch is at {limit})"
    );
    let homed = |svc: &Service| {
        let x = svc.axis("x");
        assert_eq!(x["homed"], true, "{x}");
        assert_eq!(x["homing"]["reference_set"], true, "{x}");
        // Axis position = drive position + offset: the cam's negative edge (the drive's
        // own switch, at CAM.0 counts) is at 100 to the count.
        let offset = x["position_offset"].as_f64().unwrap();
        let edge = CAM.0 as f64 / COUNTS_PER_MM + offset;
        assert!(
            (edge - 100.0).abs() <= 1.0 / COUNTS_PER_MM,
            "edge at {edge}: {x}"
        );
        // It ended moving positive, braking just past the edge onto the cam.
        let stands = x["set_position"].as_f64().unwrap();
        assert!(stands > 100.0 && stands < 105.0, "{x}");
        eprintln!("edge at {edge} (want 100), stands at {stands}");
    };
    homed(&svc);
    // The edge, by the reference switch itself: on 0.5 mm above 100, off 0.5 mm below.
    svc.ok(&["move", "x", "--to", "100.5", "--speed", "20"]);
    assert_eq!(svc.axis("x")["switches"]["reference"], true);
    svc.ok(&["move", "x", "--to", "99.5", "--speed", "20"]);
    assert_eq!(svc.axis("x")["switches"]["reference"], false);
    // No parameter, no method: the axis' last homing run, its saved parameters.
    let out = svc.ok(&["home", "x"]);
    assert!(
        out.contains("x: homed by step-to-switch; stands at 10"),
        "{out}"
    );
    homed(&svc);
    // --move-home: MoveHome again, with its own (default) parameters.
    let out = svc.ok(&["home", "x", "--move-home"]);
    assert!(out.contains("x: homed; stands at"), "{out}");
}
