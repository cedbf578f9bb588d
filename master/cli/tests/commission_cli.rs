//! `gantry commission` end to end, through the binary: `gantry run --no-rt` on the example
//! configuration with axis `x`'s simulated motor built with a commutation offset its drive
//! does not know (the chain file's `commutation_offset`, which only this test reads).
//! `gantry commission x commutation`, on the axis disabled as it starts, measures the offset
//! through the drive's open-loop current mode and its position feedback and writes it
//! (read back by SDO and judged against the hidden value, ±1° electrical), leaving the axis
//! disabled; enabled, it then moves; enabled, a second measurement is refused. `gantry commission x reversing` runs its cycles;
//! a wrong operand is refused by name; `gantry stop x` cancels a running procedure and
//! leaves the axis stopped.

mod support;

use std::process::Stdio;
use std::time::Duration;

use gantry_drives::commutation::electrical_error_deg;
use support::{Service, HOST_STALLS};

/// The simulated motor of `x`: 2¹⁷ counts, 5 pole pairs (the simulator's defaults), and
/// its true commutation offset: 9000 counts, 123.6° electrical from the drive's 0.
const COUNTS_PER_REV: u32 = 1 << 17;
const POLE_PAIRS: u32 = 5;
const HIDDEN_OFFSET: i64 = 9000;

/// The state directory the services of this test share (the measured offset is saved
/// there and written back at the next start).
fn state_dir() -> std::path::PathBuf {
    std::env::temp_dir().join(format!("gantry-state-commission-{}", std::process::id()))
}

fn start(tag: &str) -> Service {
    let axes = "# One [[axis]] per drive.";
    let config = |c: String| {
        assert!(c.contains(axes));
        let service = format!("[service]\nstate_dir = {:?}\n\n{axes}", state_dir());
        // Not real time (`--no-rt`): overruns on a loaded host are not the claim here.
        let overruns = "overrun_limit = 10 ";
        assert!(c.contains(overruns));
        c.replacen(axes, &service, 1)
            .replacen(overruns, "overrun_limit = 1000 ", 1)
    };
    Service::start_edited(tag, config, |chain| {
        let first = "[[slave]]\nkind = \"servo\"\n";
        assert!(chain.contains(first));
        // Not real time (`--no-rt`): the drives ride through the host's stalls.
        let chain = chain.replace("sync_error_limit = 32", "sync_error_limit = 1000");
        chain.replacen(
            first,
            &format!("{first}commutation_offset = {HIDDEN_OFFSET}\n"),
            1,
        )
    })
}

#[test]
fn gantry_commission_measures_the_commutation_and_runs_the_reversing_motion() {
    let _ = std::fs::remove_dir_all(state_dir());
    let mut svc = start("commission");
    // Uncommissioned (the drive would commutate 123.6° off and run the motor away in a
    // closed loop): measured from disabled, and written.
    assert_eq!(svc.axis("x")["state"], "Disabled");
    let out = svc.commission_commutation("x");
    assert!(out.contains("x: commutation offset "), "{out}");
    let written: i64 = svc
        .ok(&["sdo", "upload", "--axis", "x", "0x2100:0", "--type", "i32"])
        .trim()
        .parse()
        .unwrap();
    assert!(out.contains(&format!("offset {written} counts")), "{out}");
    let file = state_dir().join("x.params");
    assert!(
        out.contains(&format!("saved in {}", file.display())),
        "{out}"
    );
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(
        text.contains(&format!("commutation_offset = {written}")),
        "{text}"
    );
    let miss = electrical_error_deg(written, HIDDEN_OFFSET, COUNTS_PER_REV, POLE_PAIRS);
    assert!(miss.abs() <= 1.0, "{written} is {miss}° electrical off");
    // Left disabled, in CSP, the current off; enabled, it holds and moves.
    assert_eq!(
        svc.ok(&["sdo", "upload", "--axis", "x", "0x6061:0", "--type", "i8"])
            .trim(),
        "8"
    );
    assert_eq!(svc.axis("x")["state"], "Disabled");
    svc.ok(&["enable", "x"]);
    svc.ok(&["set-position", "x", "--position", "0"]);
    let out = svc.ok(&["move", "x", "--to", "2", "--speed", "10"]);
    assert!(out.contains("x: "), "{out}");
    // Enabled, the measurement is refused: it needs the power off.
    let e = svc.fails(&["commission", "x", "commutation"]);
    assert!(e.contains("x: ") && e.contains("must be disabled"), "{e}");

    // Reversing: its operands checked by name, then two cycles from 0 to 3 and back.
    let e = svc.fails(&[
        "commission",
        "x",
        "reversing",
        "--from",
        "1",
        "--to",
        "1",
        "--cycles",
        "2",
    ]);
    assert!(e.contains("x: reversing: --to"), "{e}");
    let e = svc.fails(&[
        "commission",
        "x",
        "reversing",
        "--from",
        "0",
        "--to",
        "3",
        "--cycles",
        "0",
    ]);
    assert!(e.contains("--cycles"), "{e}");
    let out = svc.ok(&[
        "commission",
        "x",
        "reversing",
        "--from",
        "0",
        "--to",
        "3",
        "--cycles",
        "2",
        "--speed",
        "20",
    ]);
    assert!(out.contains("x: reversing done, 2 cycles"), "{out}");
    let x = svc.axis("x");
    assert_eq!(x["set_position"], 0.0, "{x}");

    // Cancelled by `gantry stop x`: the procedure ends saying so, the axis stands stopped.
    let child = svc
        .command(&[
            "commission",
            "x",
            "reversing",
            "--from",
            "0",
            "--to",
            "20",
            "--cycles",
            "50",
            "--speed",
            "10",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(800));
    let e = svc.fails(&["commission", "x", "commutation"]);
    assert!(e.contains("already running"), "{e}");
    svc.ok(&["stop", "x"]);
    let out = child.wait_with_output().unwrap();
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("x: reversing cancelled"), "{e}");
    let x = svc.wait_state("x", &["Stopping"]);
    assert_eq!(x["velocity"], 0.0, "{x}");
    svc.ok(&["release", "x"]);

    // The commutation measurement cancelled too: current off, CSP again, disabled.
    svc.ok(&["disable", "x"]);
    let child = svc
        .command(&["commission", "x", "commutation"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    svc.ok(&["stop", "x"]);
    let out = child.wait_with_output().unwrap();
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("x: commutation cancelled") && e.contains("the axis is disabled"),
        "{e}"
    );
    assert_eq!(svc.axis("x")["state"], "Disabled");
    assert_eq!(
        svc.ok(&["sdo", "upload", "--axis", "x", "0x2102:0", "--type", "u16"])
            .trim(),
        "0",
        "current off"
    );
    assert_eq!(
        svc.ok(&["sdo", "upload", "--axis", "x", "0x6061:0", "--type", "i8"])
            .trim(),
        "8"
    );
    svc.ok(&["enable", "x"]);
    svc.ok(&["move", "x", "--to", "1", "--speed", "10"]);

    // A modulo axis (`c`, a rotary table of 360° through a 10:1 gear, its drive's motor
    // commutated right at power-up): the offset measured on it is its motor's, 0.
    let out = svc.commission_commutation("c");
    let c_offset: i64 = svc
        .ok(&["sdo", "upload", "--axis", "c", "0x2100:0", "--type", "i32"])
        .trim()
        .parse()
        .unwrap();
    let miss = electrical_error_deg(c_offset, 0, COUNTS_PER_REV, POLE_PAIRS);
    assert!(
        miss.abs() <= 1.0,
        "c: {c_offset} is {miss}° electrical off: {out}"
    );
    // Reversing on it: both ends within the period, and the moves go the way the numbers
    // do — 10° to 350° forwards through 180°, never the 20° across the wrap.
    svc.ok(&["enable", "c"]);
    svc.ok(&["set-position", "c", "--position", "0"]);
    let e = svc.fails(&[
        "commission",
        "c",
        "reversing",
        "--from",
        "10",
        "--to",
        "400",
        "--cycles",
        "1",
    ]);
    assert!(
        e.contains("c: reversing: --to") && e.contains("modulo period"),
        "{e}"
    );
    // Two cycles, watched; a run ended by a stall of the host is reset and run again.
    let mut attempt = 0;
    let passed_half_way = loop {
        attempt += 1;
        let mut child = svc
            .command(&[
                "commission",
                "c",
                "reversing",
                "--from",
                "10",
                "--to",
                "350",
                "--cycles",
                "2",
                "--speed",
                "360",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut passed_half_way = 0;
        while child.try_wait().unwrap().is_none() {
            let p = svc.axis("c")["position"].as_f64().unwrap();
            if (150.0..210.0).contains(&p) {
                passed_half_way += 1;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let out = child.wait_with_output().unwrap();
        if out.status.success() {
            assert!(
                String::from_utf8_lossy(&out.stdout).contains("c: reversing done, 2 cycles"),
                "{out:?}"
            );
            break passed_half_way;
        }
        let c = svc.axis("c");
        let why = c["error"].as_str().unwrap_or_default().to_string();
        assert!(
            attempt < 3 && HOST_STALLS.iter().any(|code| why.contains(code)),
            "attempt {attempt}: {} {c}",
            String::from_utf8_lossy(&out.stderr)
        );
        eprintln!("attempt {attempt} ended by a stall of the host ({why}); again");
        svc.ok(&["reset", "c"]);
        svc.wait_state("c", &["Disabled", "Standstill"]);
        svc.ok(&["enable", "c"]);
    };
    assert!(
        passed_half_way >= 2,
        "c never seen near 180° while reversing between 10° and 350°"
    );
    let c = svc.axis("c");
    assert!(
        (c["set_position"].as_f64().unwrap() - 10.0).abs() < 1e-6,
        "{c}"
    );

    // Master and simulator started again: the simulated drive powers up with its
    // commutation setting 0 (123.6° electrical off), and gantry writes the saved offset
    // back before anything enables the axis; enabled, it holds and moves.
    let (status, out) = svc.terminate();
    assert!(status.success(), "{out}");
    drop(svc);
    let mut svc = start("commission-restart");
    let back: i64 = svc
        .ok(&["sdo", "upload", "--axis", "x", "0x2100:0", "--type", "i32"])
        .trim()
        .parse()
        .unwrap();
    assert_eq!(back, written);
    svc.ok(&["enable", "x"]);
    svc.ok(&["set-position", "x", "--position", "0"]);
    svc.ok(&["move", "x", "--to", "2", "--speed", "10"]);
    let (status, out) = svc.terminate();
    assert!(status.success(), "{out}");
    assert!(
        out.contains(&format!(
            "axis x: commutation offset {written} counts written to its drive (0x2100:00) \
             from the saved parameters"
        )),
        "{out}"
    );
    let _ = std::fs::remove_dir_all(state_dir());
}
