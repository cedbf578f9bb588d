//! The `gantry` binary end to end: `profile` (single and batch) and `demo`.

use std::io::Write;
use std::process::{Command, Stdio};

fn gantry() -> Command {
    Command::new(env!("CARGO_BIN_EXE_gantry"))
}

/// Runs `gantry demo --speed 0 --out DIR EXTRA…` and returns its stdout; fails on an error exit.
fn demo(dir: &std::path::Path, extra: &[&str]) -> String {
    let out = gantry()
        .args(["demo", "--speed", "0", "--out"])
        .arg(dir)
        .args(extra)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

fn json(out: &[u8]) -> serde_json::Value {
    serde_json::from_slice(out).expect("JSON output")
}

#[test]
fn profile_prints_known_optima() {
    let out = gantry()
        .args([
            "profile", "--to-pos", "1", "--vmax", "1", "--amax", "1", "--dmax", "1", "--jmax", "1",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json(&out.stdout);
    assert!((v["duration_s"].as_f64().unwrap() - 3.1748).abs() < 1e-4);
    assert_eq!(v["phases"].as_array().unwrap().len(), 4);
    let out = gantry()
        .args([
            "profile",
            "--to-pos",
            "10",
            "--vmax",
            "2",
            "--amax",
            "1",
            "--ramp",
            "trapezoid",
        ])
        .output()
        .unwrap();
    assert!((json(&out.stdout)["duration_s"].as_f64().unwrap() - 7.0).abs() < 1e-9);
    let out = gantry()
        .args([
            "profile",
            "--from-vel",
            "-3",
            "--to-pos",
            "-2",
            "--vmax",
            "2",
            "--amax",
            "1",
            "--jmax",
            "5",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "negative operands parse");
}

#[test]
fn profile_rejects_bad_input_with_a_clear_message() {
    let out = gantry()
        .args([
            "profile", "--to-pos", "1", "--vmax", "-1", "--amax", "1", "--jmax", "1",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("vmax = -1 must be > 0"), "{err}");
    let out = gantry()
        .args(["profile", "--to-pos", "1", "--vmax", "1", "--amax", "1"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("jmax is required"));
}

#[test]
fn profile_batch_answers_every_line() {
    let mut child = gantry()
        .args(["profile", "--batch"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(b"{\"from_pos\":0,\"from_vel\":0,\"from_acc\":0,\"to_pos\":1,\"vmax\":1,\"amax\":1,\"dmax\":1,\"jmax\":1,\"ramp\":\"scurve\"}\n{\"to_pos\":\"x\"}\n{\"to_pos\":5,\"vmax\":1,\"amax\":2,\"dmax\":2,\"ramp\":\"sine\"}\n")
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    let lines: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3);
    assert!(lines[0]["plan_ns"].as_u64().is_some());
    let e = lines[1]["error"].as_str().unwrap();
    // Where, what, and serde's why.
    assert!(
        e.starts_with("line 2: not a request: invalid type: string \"x\", expected f64"),
        "{e}"
    );
    assert!(lines[2]["peak_a"].as_f64().unwrap() <= 2.0 + 1e-12);
}

#[test]
fn bus_less_demo_runs_and_prints_where_its_files_are() {
    let dir = std::env::temp_dir().join(format!("gantry-cli-demo-{}", std::process::id()));
    let text = demo(&dir, &["--bus", "none"]);
    assert!(text.contains("Halt AtActualPosition"), "{text}");
    assert!(!text.contains("EtherCAT"), "{text}");
    assert!(text.contains("demo done"));
    assert!(dir.join("trace.csv").exists() && dir.join("plot.svg").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The first line of `text` starting with `prefix`.
fn line<'a>(text: &'a str, prefix: &str) -> &'a str {
    text.lines()
        .find(|l| l.starts_with(prefix))
        .unwrap_or_else(|| panic!("no line starting with {prefix:?}:\n{text}"))
}

/// The number in `line` just before `unit` (e.g. "152" before " B on the wire").
fn number_before(line: &str, unit: &str) -> f64 {
    let head = &line[..line
        .find(unit)
        .unwrap_or_else(|| panic!("{unit:?} in {line:?}"))];
    let word = head.rsplit(' ').next().unwrap();
    word.parse()
        .unwrap_or_else(|_| panic!("a number before {unit:?} in {line:?}"))
}

/// The CSV trace as columns by name.
fn columns(csv: &str) -> std::collections::HashMap<String, Vec<f64>> {
    let mut lines = csv.lines();
    let names: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    for l in lines {
        for (c, v) in cols.iter_mut().zip(l.split(',')) {
            c.push(v.parse().unwrap());
        }
    }
    names.into_iter().zip(cols).collect()
}

#[test]
fn demo_moves_simulated_drives_over_the_in_process_network() {
    let dir = std::env::temp_dir().join(format!("gantry-cli-ecat-{}", std::process::id()));
    // No flag: the EtherCAT demo. It exits with an error when a drive faulted or saw the
    // invariant broken (issue 10 §6), which `demo` turns into a failure here; it says so
    // when it holds.
    let text = demo(&dir, &[]);
    assert!(text.contains("found 6 EtherCAT slaves"), "{text}");
    assert!(
        text.contains(">> the drives' verdict (drive-records.json): no fault"),
        "{text}"
    );
    // What it ran is a configuration a user can run: written beside the trace.
    let config = std::fs::read_to_string(dir.join("gantry.toml")).unwrap();
    assert!(
        config.contains("simulator = \"demo-servos.toml\""),
        "{config}"
    );
    assert!(dir.join("demo-servos.toml").exists());
    // The drives' own records are written beside the trace.
    let records = json(&std::fs::read(dir.join("drive-records.json")).unwrap());
    let records = records.as_array().unwrap();
    assert_eq!(records.len(), 6);
    for r in records {
        assert!(r["targets"].as_u64().unwrap() > 1000, "{r}");
        assert_eq!(r["faults"], 0, "{r}");
        assert_eq!(r["sync_missed"], 0, "{r}");
        assert_eq!(r["sync_doubled"], 0, "{r}");
    }
    // The trace: every axis ends where it was homed (0), set and actual.
    let trace = columns(&std::fs::read_to_string(dir.join("trace.csv")).unwrap());
    for name in ["x.set", "x.actual", "y.set", "y.actual"] {
        let end = *trace[name].last().unwrap();
        assert!(end.abs() < 0.01, "{name} ends at {end}");
    }
    // c at 0° after whole turns.
    for name in ["c.set_unwrapped", "c.actual_unwrapped"] {
        let end = *trace[name].last().unwrap();
        let off = (end + 180.0).rem_euclid(360.0) - 180.0;
        assert!(off.abs() < 0.01 && end > 359.0, "{name} ends at {end}");
    }
    // The synchronised axes: home at the end too (the ram at 0 mm, the rotary ones at 0°).
    for name in [
        "ram.set",
        "ram.actual",
        "m.set",
        "g1.set",
        "g1.actual",
        "g2.set",
    ] {
        let end = *trace[name].last().unwrap();
        let off = (end + 180.0).rem_euclid(360.0) - 180.0;
        assert!(off.abs() < 0.01, "{name} ends at {end}");
    }
    // From 1.5 s to 4.5 s (in gear and on the cam, through m's reversal) the trace, read
    // apart from the demo's own check: g1 travels as m, g2 half of it backwards, and the
    // ram is the eccentric's 50·(1 − cos m), which the cubic table follows to 0.011 mm.
    let times = &trace["time_s"];
    let window: Vec<usize> = (0..times.len())
        .filter(|&k| (1.5..=4.5).contains(&times[k]))
        .collect();
    assert!(window.len() > 2900, "{} samples", window.len());
    let (m, g1, g2) = (
        &trace["m.set_unwrapped"],
        &trace["g1.set_unwrapped"],
        &trace["g2.set_unwrapped"],
    );
    let k0 = window[0];
    let (lo, hi) = window.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &k| {
        (lo.min(m[k]), hi.max(m[k]))
    });
    assert!(hi - lo > 500.0, "m turned {lo}..{hi}");
    for &k in &window {
        let dm = m[k] - m[k0];
        assert!(((g1[k] - g1[k0]) - dm).abs() < 1e-6, "g1 at {}", times[k]);
        assert!(
            ((g2[k] - g2[k0]) + 0.5 * dm).abs() < 1e-6,
            "g2 at {}",
            times[k]
        );
        let stroke = 50.0 * (1.0 - trace["m.set"][k].to_radians().cos());
        let ram = trace["ram.set"][k];
        assert!((ram - stroke).abs() < 0.011, "ram {ram} at {}", times[k]);
    }
    // The demo's own check said so, with the followers' errors and peaks.
    for (axis, law) in [
        ("g1", "gear 1:1 with m"),
        ("g2", "gear -1:2 with m"),
        ("ram", "cam (eccentric.toml) on m"),
    ] {
        let l = line(&text, &format!(">> {axis}: on its {law} for "));
        assert!(l.contains(" cycles before; peak speed "), "{l}");
    }
    assert!(dir.join("plot.svg").exists());
    assert!(dir.join("eccentric.toml").exists());
    // The axis group xy: the rounded rectangle back on its start corner, its XY path
    // plotted beside the time plots; x along its right side (x alone never goes so far).
    let l = line(
        &text,
        ">> xy: the rounded rectangle ended on its start corner (20, 0) and the group at home",
    );
    // Every junction of the rectangle passed in motion (the demo itself fails a path off
    // the rectangle by more than the reported bound).
    assert!(
        l.contains("; 7 corners passed in motion, each within "),
        "{l}"
    );
    let path = line(&text, "path:  ");
    assert!(path.ends_with("xy.svg"), "{path}");
    let xy = std::fs::read_to_string(dir.join("xy.svg")).unwrap();
    assert!(xy.contains("x.set / y.set") && xy.contains("x.actual / y.actual"));
    let (x, y) = (&trace["x.set"], &trace["y.set"]);
    assert!(x
        .iter()
        .zip(y)
        .any(|(&x, &y)| x > 199.9 && (20.0..100.0).contains(&y)));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// What a commissioning engineer reads of the bus, and the modulo axis across its wrap:
/// the kernel's set position wraps from near 360° to near 0° (and back), while the drive's
/// own record shows its target never stepped beyond `vmax · T` in a cycle.
#[test]
fn demo_prints_the_bus_and_turns_the_modulo_axis_across_its_wrap_without_a_step() {
    let dir = std::env::temp_dir().join(format!("gantry-cli-bus-{}", std::process::id()));
    let text = demo(&dir, &["--bus", "ethercat"]);
    // The slaves found: position, station address, name, vendor and product.
    for i in 0..6 {
        let l = line(&text, &format!("  {i}: "));
        assert!(
            l.starts_with(&format!(
                "  {i}: {:#06x} SIM-SERVO (vendor: 0x00000a5a, product 0x00000402",
                0x1000 + i
            )),
            "{l}"
        );
    }
    // AL state and process data per slave, as the master has them once in OP.
    line(&text, ">> every slave reported OP");
    // x: the minimal CSP layout with its switches (0x60FD) and touch probe (0x60B8…0x60BC).
    for (i, axis, inputs, outputs) in [
        (0, "x", "24", "8"),
        (1, "y", "15", "7"),
        (2, "c", "15", "7"),
        (3, "g1", "15", "7"),
        (4, "g2", "15", "7"),
        (5, "ram", "15", "7"),
    ] {
        let l = line(&text, &format!("   {i}      "));
        let words: Vec<&str> = l.split_whitespace().collect();
        assert_eq!(
            words,
            [&i.to_string(), "OP", inputs, "B", outputs, "B", axis],
            "{l}"
        );
    }
    let image = line(&text, ">> process data: ");
    assert!(
        image.starts_with(
            ">> process data: 142 B in 1 LRW datagram(s), expected working counter 18"
        ),
        "{image}"
    );
    // Bytes on the wire: the image and every header, the same at start and at the end.
    let wire = number_before(image, " B on the wire per cycle");
    assert!(wire >= 142.0 + 14.0 + 2.0 + 10.0 + 2.0 + 4.0, "{image}");
    // x homed on its reference cam and the index pulse beyond it: x = 0 mm is the index
    // pulse at drive count 1000, as the simulated drive recorded crossing it.
    line(
        &text,
        ">> x homed: x = 0 mm stands at drive count 1000, the index pulse its drive crossed at 1000",
    );
    assert!(
        text.find(">> x: MoveHome on its reference switch") < text.find(">> x: S-curve MovePtp"),
        "x homes before it moves"
    );
    let end = line(&text, ">> on the wire: ");
    assert_eq!(number_before(end, " B per cycle"), wire, "{end}");
    // Distributed clocks: SYNC0 at the cycle time, the frames held a quarter period after
    // SYNC0 all through OP.
    let dc = line(&text, ">> distributed clocks: SYNC0 every 1000 µs; ");
    assert!(dc.contains("(the cycle holds them at 250.0 µs)"), "{dc}");
    let held = line(&text, ">> distributed clocks: in OP the frames reached");
    let (lo, hi) = (
        number_before(held, " and "),
        number_before(held, " µs into the SYNC0 period"),
    );
    assert!((240.0..=hi).contains(&lo) && hi <= 260.0, "{held}");
    // Cycle figures: nothing lost on a lockstep network.
    let cycles = line(&text, ">> cycles: ");
    assert!(
        cycles.contains("lost frames 0; working-counter errors 0; overruns 0"),
        "{cycles}"
    );
    assert!(number_before(cycles, " (") > 3000.0, "{cycles}");
    // Every axis at the end, at home, its drive still enabled before the shutdown.
    line(&text, ">> the axes at the end:");
    for axis in ["x", "y", "c", "g1", "g2", "ram"] {
        let l = line(&text, &format!("   {axis}: "));
        assert!(
            l.starts_with(&format!("   {axis}: Standstill, set 0.0000, actual ")),
            "{l}"
        );
        assert!(l.ends_with("drive Operation enabled"), "{l}");
    }
    let l = line(&text, "   m: ");
    assert_eq!(
        l, "   m: Standstill, set 0.0000, actual 0.0000, no drive (virtual)",
        "{l}"
    );
    let said = line(&text, ">> c: crossed its wrap (360 → 0) ");
    // The kernel's set position of c wraps, forward at positive speed and backward at
    // negative, as the demo says.
    let trace = columns(&std::fs::read_to_string(dir.join("trace.csv")).unwrap());
    let (set, v) = (&trace["c.set"], &trace["c.v"]);
    let (mut forward, mut backward) = (0, 0);
    for k in 1..set.len() {
        if set[k - 1] > 350.0 && set[k] < 10.0 && v[k] > 0.0 {
            forward += 1;
        }
        if set[k - 1] < 10.0 && set[k] > 350.0 && v[k] < 0.0 {
            backward += 1;
        }
    }
    assert!(
        forward >= 2 && backward >= 1,
        "{forward} forward, {backward} backward"
    );
    assert!(
        said.contains(&format!("{forward} times forward and {backward} backward")),
        "{said}"
    );
    // The drive saw no step: c's target changed at most vmax · T + 1 count per cycle —
    // 720°/s through 10:1 on 2^17 counts per motor revolution, 1 ms: 2621.44 counts.
    let bound = (720.0 / 360.0 * 10.0 * 131_072.0 * 1e-3_f64).floor() as u64 + 1;
    let records = json(&std::fs::read(dir.join("drive-records.json")).unwrap());
    let c = &records[2];
    let step = c["max_target_step_counts"].as_u64().unwrap();
    assert!(
        step <= bound && step > bound / 2,
        "c's largest step {step}, bound {bound}"
    );
    assert_eq!(c["faults"], 0, "{c}");
    assert!(
        said.contains(&format!(
            "at most {step} counts in a cycle (vmax · T: {bound} counts)"
        )),
        "{said}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The capture must be readable by Wireshark's EtherCAT dissector: every frame dissected,
/// none malformed, no expert warning. Needs `tshark`, which `deploy/test.sh` installs.
#[test]
#[ignore = "needs tshark; deploy/test.sh installs it and runs ignored tests"]
fn pcap_of_the_ethercat_demo_dissects_clean_in_tshark() {
    let dir = std::env::temp_dir().join(format!("gantry-cli-pcap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let pcap = dir.join("run.pcap");
    let out = gantry()
        .args(["demo", "--speed", "0", "--out"])
        .arg(&dir)
        .arg("--pcap")
        .arg(&pcap)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let tshark = |filter: &str| -> usize {
        let out = Command::new("tshark")
            .args(["-n", "-r"])
            .arg(&pcap)
            .args(["-Y", filter])
            .output()
            .expect("tshark is installed (deploy/test.sh installs it)");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).lines().count()
    };
    let all = tshark("frame");
    let ecat = tshark("ecat");
    let bad = tshark("_ws.malformed || _ws.expert.severity >= warning");
    eprintln!("pcap: {all} frames, {ecat} dissected as EtherCAT, {bad} malformed or warned");
    assert!(all > 1000, "a whole demo run is captured: {all} frames");
    assert_eq!(ecat, all, "every frame is EtherCAT");
    assert_eq!(bad, 0, "no malformed frame, no expert warning");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `rt-check --can N`: the SYNC figures of a CANopen cycle thread on N simulated servos,
/// one SYNC per cycle; a node count out of 1..=127 is refused by name.
#[test]
fn rt_check_can_measures_the_sync_of_simulated_servos() {
    let out = gantry()
        .args([
            "rt-check",
            "--can",
            "2",
            "--seconds",
            "0.3",
            "--cycle-us",
            "2000",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("2 simulated servos"), "{text}");
    assert!(text.contains("SYNC |interval − period|  p50"), "{text}");
    assert!(text.contains("SYNC sent − deadline     p50"), "{text}");
    assert!(text.contains("150 SYNCs in 150 cycles"), "{text}");
    let bad = gantry().args(["rt-check", "--can", "0"]).output().unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("--can 0"), "{err}");
}

#[test]
fn rt_check_reports_the_machine_and_measures() {
    let out = gantry()
        .args(["rt-check", "--seconds", "0.3", "--cycle-us", "1000"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    for check in [
        "kernel",
        "capabilities",
        "CPU isolation",
        "CPU frequency governor",
        "CPU idle states (PM QoS)",
        "RT throttling",
    ] {
        assert!(text.contains(check), "{check}: {text}");
    }
    assert!(text.contains("gantry      p50"), "{text}");
    let bad = gantry()
        .args(["rt-check", "--seconds", "-1"])
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--seconds -1"));
}

/// With rt-tests installed (deploy/test.sh installs it), the same figures from cyclictest
/// and the ratio.
#[test]
#[ignore = "needs cyclictest (rt-tests) and SCHED_FIFO; deploy/test.sh runs it"]
fn rt_check_measures_beside_cyclictest() {
    let out = gantry()
        .args(["rt-check", "--seconds", "0.5", "--cycle-us", "1000"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("cyclictest  p50"), "{text}");
    assert!(text.contains("ratio gantry/cyclictest"), "{text}");
    assert!(!text.contains("NOT real time"), "{text}");
}

#[test]
fn an_error_prints_what_failed_and_its_cause_once() {
    let dir = std::env::temp_dir().join(format!("gantry-cli-chain-{}", std::process::id()));
    let pcap = dir.join("no-such-dir").join("x.pcap");
    let out = gantry()
        .args(["demo", "--speed", "0", "--bus", "ethercat", "--out"])
        .arg(&dir)
        .arg("--pcap")
        .arg(&pcap)
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains(&format!(
            "gantry: cannot write {}: No such file or directory",
            pcap.display()
        )),
        "{e}"
    );
    assert_eq!(e.matches("No such file").count(), 1, "{e}");
}

/// `gantry demo --bus canopen`: four CiA-402 servos as CANopen nodes on the in-memory
/// CAN bus at 1 Mbit/s, brought up (boot-up, identity, PDOs by SDO, NMT start) and driven
/// through the EtherCAT demo's script in lockstep at 2 ms; no TPDO lost, the drives'
/// records judged, every axis home at the end, files written beside a configuration a
/// user can run.
#[test]
fn demo_moves_simulated_canopen_drives_over_the_in_memory_can_bus() {
    let dir = std::env::temp_dir().join(format!("gantry-cli-canopen-{}", std::process::id()));
    let text = demo(&dir, &["--bus", "canopen"]);
    line(
        &text,
        "CANopen: 4 nodes booted after NMT reset communication",
    );
    // Each node, what the bring-up read of it and its PDOs.
    // x: the minimal layout with its switches and touch probe (3 TPDOs).
    for (node, axis, tpdos, outputs, inputs) in [
        (1, "x", "3", "8", "24"),
        (2, "y", "2", "7", "15"),
        (3, "z", "2", "7", "15"),
        (4, "c", "2", "7", "15"),
    ] {
        let l = line(&text, &format!("   {node}     0x00020192"));
        let words: Vec<&str> = l.split_whitespace().collect();
        assert_eq!(
            words,
            [
                &node.to_string(),
                "0x00020192",
                "0x00000A5A",
                "0x00000402",
                "1",
                tpdos,
                outputs,
                "B",
                inputs,
                "B",
                axis
            ],
            "{l}"
        );
    }
    let load = line(
        &text,
        ">> every node Operational; each cycle: RPDOs, SYNC, TPDOs — ",
    );
    assert!(load.contains("of 2000 µs at 1000 kbit/s"), "{load}");
    // x with its switches and touch probe: 1757 bits, 90 % of the reply window.
    assert!(load.contains("TPDOs — 1757 bits of 2000 µs"), "{load}");
    assert!(
        load.contains("(90 % of the cycle's reply window)"),
        "{load}"
    );
    // Nothing lost on a lockstep bus; 14 frames a cycle: 4 RPDOs, the SYNC, 9 TPDOs.
    let cycles = line(&text, ">> cycles: ");
    assert!(
        cycles.contains("TPDO sets lost 0 (incomplete 0); malformed frames 0; overruns 0"),
        "{cycles}"
    );
    assert!(number_before(cycles, "; TPDO") > 2500.0, "{cycles}");
    let bus = line(&text, ">> on the bus: ");
    let per_cycle = number_before(bus, " per cycle;");
    assert!((13.9..=14.2).contains(&per_cycle), "{bus}");
    line(
        &text,
        ">> x homed: x = 0 mm stands at drive count 1000, the index pulse its drive crossed at 1000",
    );
    // The clean shutdown: every node released from watching gantry's SYNC and heartbeat.
    line(
        &text,
        "CANopen: nodes pre-operational; SYNC watchdog and heartbeat consumer taken back on \
         node(s) 1, 2, 3, 4 in",
    );
    line(&text, ">> the axes at the end:");
    for axis in ["x", "y", "z", "c"] {
        let l = line(&text, &format!("   {axis}: "));
        assert!(
            l.starts_with(&format!("   {axis}: Standstill, set 0.0000, actual ")),
            "{l}"
        );
        assert!(l.ends_with("drive Operation enabled"), "{l}");
    }
    assert!(
        text.contains(">> the drives' verdict (drive-records.json): no fault"),
        "{text}"
    );
    let records = json(&std::fs::read(dir.join("drive-records.json")).unwrap());
    let records = records.as_array().unwrap();
    assert_eq!(records.len(), 4);
    for r in records {
        assert!(r["targets"].as_u64().unwrap() > 2500, "{r}");
        assert_eq!(r["faults"], 0, "{r}");
        assert_eq!(r["sync_missed"], 0, "{r}");
        assert_eq!(r["sync_doubled"], 0, "{r}");
    }
    let config = std::fs::read_to_string(dir.join("gantry.toml")).unwrap();
    assert!(config.contains("kind = \"canopen\""), "{config}");
    assert!(dir.join("demo-can-servos.toml").exists());
    let trace = columns(&std::fs::read_to_string(dir.join("trace.csv")).unwrap());
    for name in ["x.actual", "y.actual", "z.actual"] {
        let end = *trace[name].last().unwrap();
        assert!(end.abs() < 0.01, "{name} ends at {end}");
    }
    // z went down to 50 mm on the way.
    let z = trace["z.actual"].iter().copied().fold(f64::MIN, f64::max);
    assert!((z - 50.0).abs() < 0.05, "z reached {z}");
    assert!(std::fs::read_to_string(dir.join("plot.svg"))
        .unwrap()
        .contains("over CANopen"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `gantry dcf` on a vendor's EDS (the ACME SX400 fixture of the EDS reader's tests).
#[test]
fn dcf_writes_the_vendor_eds_with_what_the_bring_up_configures() {
    let dir = std::env::temp_dir().join(format!("gantry-cli-dcf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let acme = include_str!("../../../drives/tests/eds/acme_sx400.eds");
    std::fs::write(dir.join("sx400.eds"), acme).unwrap();
    let config = dir.join("c.toml");
    let text = "[bus]\nkind = \"canopen\"\ninterface = \"can0\"\nbitrate = 1000000\n\
                cycle_us = 1000\n[[axis]]\nname = \"x\"\nnode = 9\neds = \"sx400.eds\"\n\
                scaling = { counts_per_motor_rev = 1000, units_per_load_rev = 1.0 }\n\
                max = { speed = 10.0, acceleration = 100.0, jerk = 1000.0 }\n";
    std::fs::write(&config, text).unwrap();
    let out = dir.join("x.dcf");
    let run = gantry()
        .args(["dcf", "--config"])
        .arg(&config)
        .args(["--axis", "x", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{run:?}");
    assert_eq!(
        String::from_utf8_lossy(&run.stdout).trim(),
        format!("gantry: DCF of axis \"x\" written to {}", out.display())
    );
    let dcf = gantry_drives::canopen::eds::load(&out).unwrap_or_else(|e| panic!("{e}"));
    let c = dcf.commissioning.as_ref().unwrap();
    assert_eq!(
        (c.node_id, c.baudrate_kbit, c.node_name.as_str()),
        (9, 1000, "x")
    );
    let value = |index: u16, sub: u8| {
        dcf.entry(index, sub)
            .and_then(|e| e.parameter_value.as_ref())
            .and_then(|v| v.integer_on(9))
    };
    assert_eq!(
        value(0x1600, 1),
        Some(0x607A_0020),
        "RPDO1: the target first"
    );
    assert_eq!(value(0x1400, 1), Some(0x209));
    assert_eq!(value(0x1017, 0), Some(100));
    // The consumer of gantry's heartbeat: node 127, 300 ms.
    assert_eq!(value(0x1016, 1), Some(127 << 16 | 300));
    assert_eq!(value(0x1006, 0), None, "the SX400 has no 0x1006");
    assert_eq!(dcf.device_info.product_name, "SX400");
    // A layout the drive cannot take: the configuration's error, a failing exit.
    std::fs::write(
        dir.join("sx400.eds"),
        acme.replacen("NrOfTXPDO=4", "NrOfTXPDO=1", 1),
    )
    .unwrap();
    let run = gantry()
        .args(["dcf", "--config"])
        .arg(&config)
        .args(["--axis", "x", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!run.status.success());
    let e = String::from_utf8_lossy(&run.stderr);
    assert_eq!(
        e.trim(),
        format!(
            "gantry: {}:9: axis[0].eds: CANopen node 9 (axis \"x\"): its process data need 2 \
             TPDOs (15 input bytes in PDOs of 8), the drive has 1 (NrOfTXPDO in {})",
            config.display(),
            dir.join("sx400.eds").display()
        )
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
