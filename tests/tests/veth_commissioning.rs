//! `gantry commission` and `gantry home` end to end over a veth pair: one
//! `gantry run` in real time on the shipped veth example, `gantry-sim` recording on the
//! pair's other end, the CLI against the service's socket, both processes started twice.
//!
//! The chain's first servo (axis `x`) has switch cams (`[slave.switches]`: the home cam
//! from 10 mm to just under 12 mm, limit switches far out) and a commutation offset its
//! drive does not know (`commutation_offset`, which only this test reads); the service has
//! a state directory.
//!
//! 1. `gantry commission x commutation` on the axis disabled as it starts: the offset read
//!    back from the drive (0x2100) is within ±1° electrical of the hidden one, and saved.
//! 2. Enabled, `gantry home x` (MoveHome on the home switch's edge, a reference offset and
//!    a normal position of its own): the reference lands on the simulated edge within one
//!    count. The drive records (`gantry-sim --record`) carry no positions, so this is read
//!    from the status: the axis' position offset (axis position minus drive position, set
//!    by homing from the drive's touch-probe latch, not a sampled position) gives the
//!    count that reads NormalPosition − ReferenceOffset, which must be the edge's.
//! 3. `gantry home x --drive --method 19`: the configured method (35, the current
//!    position) is replaced, and the drive homes itself on the same edge; a MoveHome after
//!    it, with the parameters of step 2 left out, finds that edge exactly where the
//!    drive's home offset (0x607C) put it. A move in between.
//! 4. Both processes stopped and started again: the saved offset is back in the drive
//!    (0x2100 by `gantry sdo`), and `gantry home x` without parameters runs with the saved
//!    ones (their normal position is not the default's) onto the same edge.
//!
//! What reached the drives is judged by the drive invariant on the records of both runs.
//! This VM's kernel does not preempt: now and then the master's thread stalls for
//! milliseconds. Master and drives are set to ride through stalls of up to 20 ms (lost
//! frames in a row, sync errors: the example stops at 3 ms and 10 ms); after a longer one
//! every axis stops; such a stop —
//! and only such a stop — is reset as an operator would, counted, the command repeated,
//! and the count printed and bounded (as `veth_service.rs`). Needs root;
//! `deploy/test.sh` runs it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use gantry_drives::commutation::electrical_error_deg;
use gantry_tests::invariant::{assert_record_invariants, DriveUnderTest, TestConditions};
use gantry_tests::netns::{built_binary, start_gantry_sim_recording, Reaped, SimProcess, VethPair};

/// The simulated motor of `x`: 2¹⁷ counts, 5 pole pairs (the simulator's defaults).
const COUNTS_PER_REV: u32 = 1 << 17;
const POLE_PAIRS: u32 = 5;
/// Its true commutation offset (counts): 233.5° electrical from the drive's 0.
const HIDDEN_OFFSET: i64 = 17_000;
/// Counts per mm of the example's `x`: 2¹⁷ counts per revolution, 5 mm lead.
const COUNTS_PER_MM: f64 = 131_072.0 / 5.0;
/// The home cam of the first servo (counts): 10 mm to just under 12 mm.
const CAM: (i64, i64) = (262_144, 314_572);
/// MoveHome's reference offset (where it ends, from the reference) and normal position
/// (what that place reads); neither is the default, 0.
const REFERENCE_OFFSET: f64 = 1.0;
const NORMAL_POSITION: f64 = 3.0;
/// The drive homing's home offset (mm; `[axis.drive_homing]`).
const HOME_OFFSET_MM: f64 = 2.0;
/// The example's `x` line that the test replaces.
const X_PDO: &str =
    "pdo = \"csp\"                   # mapped by SDO in PreOp: + velocity, torque, error code";
const AXES: &str = "# One [[axis]] per drive.";
const SERVO: &str = "[[slave]]\nkind = \"servo\"\n";
/// The example's lost-frame limit (3 in a row), which this test raises.
const LOST_FRAMES: &str = "lost_frames_limit = 3 ";
/// Timing stops one command may meet before the test fails (every one is reported).
/// `veth_service.rs` allows three in its whole run of about 5 s; this one runs 30 s and
/// more, and its commutation measurement alone several seconds: with the other builds of
/// this machine running, an idle service stopped every 5 s or so (measured: 5 stops in
/// 20 s, 98 frames lost in 27 000 cycles).
const MAX_STOPS_PER_COMMAND: usize = 3;

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/examples")
}

/// The veth example on `interface`, with the state directory and `x` wired to its
/// drive's switches, drive homing configured with method 35 (home where it stands) so
/// that `--method` has to replace it. Everything else as shipped: real time, its overrun
/// and lost-frame limits.
fn gantry_config(interface: &str, state: &Path) -> String {
    let example = std::fs::read_to_string(examples().join("veth-4-axes.toml")).unwrap();
    for needle in ["interface = \"veth-master\"", X_PDO, AXES, LOST_FRAMES] {
        assert!(example.contains(needle), "the example has {needle:?}");
    }
    example
        .replace(
            "interface = \"veth-master\"",
            &format!("interface = {interface:?}"),
        )
        // The master rides through this VM's stalls of up to 20 ms (as `vcan_master.rs`'s
        // does through the emulator's), and so do the drives (see `chain`); a longer stall
        // still stops them, and that stop is a timing stop.
        .replacen(LOST_FRAMES, "lost_frames_limit = 20 ", 1)
        .replacen(
            X_PDO,
            &format!(
                "pdo = \"csp-minimal\"\nswitches = {{ negative_limit = \"drive\", \
                 positive_limit = \"drive\", reference = \"drive\" }}\n\
                 drive_homing = {{ method = 35, speed_switch = 20.0, speed_zero = 2.0, \
                 acceleration = 200.0, home_offset = {HOME_OFFSET_MM:?}, timeout = 20.0 }}"
            ),
            1,
        )
        .replacen(
            AXES,
            &format!(
                "[service]\nstate_dir = {:?}\n\n{AXES}",
                state.display().to_string()
            ),
            1,
        )
}

/// The shipped chain with the first servo's hidden commutation offset and switch cams.
fn chain() -> String {
    let chain = std::fs::read_to_string(examples().join("sim-4-servos.toml")).unwrap();
    assert!(chain.contains(SERVO) && chain.contains("sync_error_limit = 32"));
    // The drives ride through about thirty periods without a setpoint (the example's ten).
    let chain = chain.replace("sync_error_limit = 32", "sync_error_limit = 100");
    chain.replacen(
        SERVO,
        &format!(
            "{SERVO}commutation_offset = {HIDDEN_OFFSET}\n[slave.switches]\n\
             negative_limit = [-9000000000, -1310720]\n\
             positive_limit = [13107200, 9000000000]\nhome = [{}, {}]\n",
            CAM.0, CAM.1
        ),
        1,
    )
}

/// One start of both processes.
struct Run {
    sim: SimProcess,
    service: Reaped,
    socket: PathBuf,
    records: PathBuf,
}

fn start(pair: &VethPair, dir: &Path, n: usize) -> Run {
    let records = dir.join(format!("drive-records-{n}.json"));
    let sim = start_gantry_sim_recording(
        &pair.sim_ns,
        &pair.sim_if,
        &dir.join("sim-4-servos.toml"),
        4,
        Some(&records),
    );
    let socket = dir.join(format!("gantry-{n}.sock"));
    let service = Command::new("ip")
        .args(["netns", "exec", &pair.master_ns])
        .arg(built_binary("gantry").unwrap())
        .args(["run", "--config"])
        .arg(dir.join("gantry.toml"))
        .arg("--socket")
        .arg(&socket)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut service = Reaped::new(service);
    let end = Instant::now() + Duration::from_secs(30);
    while std::os::unix::net::UnixStream::connect(&socket).is_err() {
        if let Some(status) = service.child().try_wait().unwrap() {
            let out = service.take().wait_with_output().unwrap();
            panic!(
                "gantry run ended ({status}): {}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
        }
        assert!(Instant::now() < end, "no control socket");
        std::thread::sleep(Duration::from_millis(50));
    }
    Run {
        sim,
        service,
        socket,
        records,
    }
}

impl Run {
    /// Checks the cycle's figures, stops the service (SIGTERM) and then the simulator: the
    /// service's stdout, and the file of the drives' records.
    /// Also the frames since `since` (the run's start-up, its first cycles, not counted).
    fn stop(mut self, shell: &Shell, since: Frames) -> (String, PathBuf, Frames) {
        let status = shell.status();
        let table = shell.table();
        eprintln!("{table}");
        assert_eq!(status["real_time"], true, "{status}");
        assert_eq!(status["overrun_stop"], false, "{table}");
        // A reply later than the next cycle's start is lost; on this non-real-time kernel
        // a few are (the cycle counts them and rides through). Judged over both runs.
        let all = Frames::of(&status);
        let frames = Frames {
            cycles: all.cycles - since.cycles,
            lost: all.lost - since.lost,
        };
        eprintln!(
            "{} cycles, {} frames lost ({} and {} in the start-up)",
            frames.cycles, frames.lost, since.cycles, since.lost
        );
        nix::sys::signal::kill(
            nix::unistd::Pid::from_raw(self.service.child().id() as i32),
            nix::sys::signal::Signal::SIGTERM,
        )
        .unwrap();
        let out = self.service.take().wait_with_output().unwrap();
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(
            out.status.success(),
            "{text}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let gaps = self.sim.stop().expect("gantry-sim's summary");
        eprintln!("{}", gaps.line);
        assert_eq!(gaps.write_gaps_us.len(), 4, "{}", gaps.line);
        (text, self.records, frames)
    }
}

/// Cycles run and frames lost in one run of the service.
#[derive(Clone, Copy, Debug)]
struct Frames {
    cycles: u64,
    lost: u64,
}

impl Frames {
    /// The counts of a `gantry status --json`.
    fn of(status: &serde_json::Value) -> Self {
        Self {
            cycles: status["cycles"].as_u64().unwrap(),
            lost: status["bus"]["lost_frames"].as_u64().unwrap(),
        }
    }
}

/// The CLI against one run's socket; timing stops counted across runs.
struct Shell {
    gantry: PathBuf,
    socket: PathBuf,
    stops: Vec<String>,
}

impl Shell {
    fn cli(&self, args: &[&str]) -> Output {
        Command::new(&self.gantry)
            .args(args)
            .arg("--socket")
            .arg(&self.socket)
            .output()
            .unwrap()
    }

    /// A command that must succeed at once (no motion: queries and SDO transfers).
    fn ok(&self, args: &[&str]) -> String {
        let out = self.cli(args);
        assert!(
            out.status.success(),
            "{args:?}: {}{}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr),
            self.table()
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    fn status(&self) -> serde_json::Value {
        let out = self.cli(&["status", "--json"]);
        assert!(out.status.success(), "status --json: {out:?}");
        serde_json::from_slice(&out.stdout).unwrap()
    }

    /// The service's cycles and lost frames so far.
    fn frames(&self) -> Frames {
        Frames::of(&self.status())
    }

    fn table(&self) -> String {
        String::from_utf8_lossy(&self.cli(&["status"]).stdout).into_owned()
    }

    fn axis(&self, name: &str) -> serde_json::Value {
        self.status()["axes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|a| a["name"] == name)
            .unwrap()
            .clone()
    }

    fn sdo_i32(&self, object: &str) -> i64 {
        let text = self.ok(&["sdo", "upload", "--axis", "x", object, "--type", "i32"]);
        text.trim()
            .parse()
            .unwrap_or_else(|e| panic!("{object}: {text:?}: {e}"))
    }

    /// Whether the axes stand stopped by this VM's timing, and only by it: every axis
    /// error is the bus' (0x8100: frames lost in a row) or a drive's sync error (0x8700),
    /// and every drive's bus fault one of those two (as `veth_realtime.rs` judges its
    /// stops). What stopped them: `Ok` if that, else `Err`.
    fn timing_stop(&self) -> Result<String, String> {
        let status = self.status();
        // `x` maps csp-minimal, without the error code (0x603F): its drive fault reads
        // 0xFF00 ("not mapped") in the status; the drive's own code is read by SDO.
        let errors: Vec<String> = status["axes"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|a| {
                let name = a["name"].as_str()?;
                let error = a["error"].as_str()?;
                if !error.contains("drive fault 0xFF00") {
                    return Some(format!("{name}: {error}"));
                }
                let out = self.cli(&["sdo", "upload", "--axis", name, "0x603F:0", "--type", "u16"]);
                let text = String::from_utf8_lossy(&out.stdout);
                Some(match text.trim().parse::<u16>() {
                    Ok(code) => format!("{name}: drive fault 0x{code:04X} (0x603F by SDO)"),
                    Err(_) => format!(
                        "{name}: {error}; 0x603F: {text}{}",
                        String::from_utf8_lossy(&out.stderr)
                    ),
                })
            })
            .collect();
        let faults: Vec<String> = status["drives"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|d| Some(format!("{}: {}", d["axis"], d["bus_fault"].as_str()?)))
            .collect();
        let timing = !errors.is_empty()
            && errors
                .iter()
                .all(|e| e.contains("drive fault 0x8100") || e.contains("drive fault 0x8700"))
            && faults.iter().all(|f| {
                f.contains("frames lost in a row") || f.contains("left OP: now Safe-Operational")
            });
        let what = format!("{errors:?} {faults:?}");
        if timing {
            Ok(what)
        } else {
            Err(what)
        }
    }

    /// Resets every stopped axis, `x` enabled again if `enable`, as an operator would; a
    /// timing stop meanwhile (and only that) starts it again, within 10 s.
    fn recover(&mut self, enable: bool) {
        let end = Instant::now() + Duration::from_secs(10);
        'again: loop {
            assert!(
                Instant::now() < end,
                "no recovery in 10 s: {}",
                self.table()
            );
            for a in self.status()["axes"].as_array().unwrap().clone() {
                if a["error"].is_null() {
                    continue;
                }
                let name = a["name"].as_str().unwrap();
                if !self.cli(&["reset", name]).status.success() {
                    // A slave that left OP comes back with the reset; the bus may still
                    // be recovering.
                    std::thread::sleep(Duration::from_millis(100));
                    continue 'again;
                }
            }
            if enable && self.axis("x")["state"] == "Disabled" {
                let out = self.cli(&["enable", "x"]);
                if !out.status.success() {
                    let timing = self.timing_stop();
                    assert!(
                        timing.is_ok(),
                        "enable x while recovering: {}{timing:?}",
                        String::from_utf8_lossy(&out.stderr)
                    );
                    continue 'again;
                }
            }
            return;
        }
    }

    /// Counts a timing stop `why` of command `what`: at most [`MAX_STOPS_PER_COMMAND`] for
    /// one command.
    fn count_stop(&mut self, what: &str, why: String, per_command: &mut usize) {
        *per_command += 1;
        eprintln!("timing stop during {what}: {why}; reset, repeated");
        self.stops.push(format!("{what}: {why}"));
        assert!(
            *per_command <= MAX_STOPS_PER_COMMAND,
            "{what}: {per_command} timing stops in a row: {:?}",
            self.stops
        );
    }

    /// A command that must succeed; a timing stop of this VM (and only that) is reset,
    /// counted, and the command repeated, `x` enabled again first if `enabled`. Its
    /// stdout.
    fn step(&mut self, args: &[&str], enabled: bool) -> String {
        let mut per_command = 0;
        loop {
            let out = self.cli(args);
            if out.status.success() {
                return String::from_utf8_lossy(&out.stdout).into_owned();
            }
            let timing = self.timing_stop();
            assert!(
                timing.is_ok(),
                "{args:?}: {}{}\n{}\nstopped by: {timing:?}\nearlier timing stops: {:?}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr),
                self.table(),
                self.stops
            );
            self.count_stop(&format!("{args:?}"), timing.unwrap(), &mut per_command);
            self.recover(enabled);
        }
    }

    /// After an idle stretch: a timing stop meanwhile is recovered the same way.
    fn settle(&mut self, enabled: bool) {
        if let Ok(why) = self.timing_stop() {
            self.count_stop("idle", why, &mut 0);
            self.recover(enabled);
        }
        let x = self.axis("x");
        assert!(x["error"].is_null(), "{x}");
    }

    /// Where MoveHome put the reference, in the drive's counts. MoveHome ends at the
    /// reference plus ReferenceOffset and calls that place NormalPosition (seed 000
    /// §6.3.2.1), so the reference reads NormalPosition − ReferenceOffset; the axis
    /// position is the drive position plus the position offset.
    fn reference_count(&self) -> f64 {
        let x = self.axis("x");
        assert_eq!(x["homed"], true, "{x}");
        assert_eq!(x["homing"]["reference_set"], true, "{x}");
        (NORMAL_POSITION - REFERENCE_OFFSET - x["position_offset"].as_f64().unwrap())
            * COUNTS_PER_MM
    }
}

/// The MoveHome call with every parameter given (step 2).
const HOME: &[&str] = &[
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
    "1",
    "--normal-position",
    "3",
];

#[test]
#[ignore = "needs root (network namespaces) and the built binaries; deploy/test.sh runs it"]
fn commission_and_home_over_veth_across_a_restart() {
    let began = Instant::now();
    let pair = VethPair::create("com").expect("veth pair in two namespaces");
    let dir = std::env::temp_dir().join(format!("gantry-veth-com-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let state = dir.join("state");
    std::fs::write(
        dir.join("gantry.toml"),
        gantry_config(&pair.master_if, &state),
    )
    .unwrap();
    std::fs::write(dir.join("sim-4-servos.toml"), chain()).unwrap();
    let stands_at = |v: f64| format!("x: homed; stands at {v:.3}");

    let run = start(&pair, &dir, 1);
    let mut shell = Shell {
        gantry: built_binary("gantry").unwrap(),
        socket: run.socket.clone(),
        stops: Vec::new(),
    };
    let started = shell.frames();

    // 1. Commutation, measured from disabled, written, judged, saved.
    assert_eq!(shell.axis("x")["state"], "Disabled");
    let out = shell.step(&["commission", "x", "commutation"], false);
    assert!(out.contains("x: commutation offset "), "{out}");
    let written = shell.sdo_i32("0x2100:0");
    assert!(out.contains(&format!("offset {written} counts")), "{out}");
    let miss = electrical_error_deg(written, HIDDEN_OFFSET, COUNTS_PER_REV, POLE_PAIRS);
    eprintln!("commutation offset {written} counts, {miss:.3}° electrical off the hidden one");
    assert!(miss.abs() <= 1.0, "{written} is {miss}° electrical off");
    let file = state.join("x.params");
    assert!(
        out.contains(&format!("saved in {}", file.display())),
        "{out}"
    );
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(
        text.contains(&format!("commutation_offset = {written}")),
        "{text}"
    );
    // A timing stop right after the measurement is recovered as one during it.
    shell.settle(false);
    assert_eq!(shell.axis("x")["state"], "Disabled");

    // 2. Enabled, MoveHome onto the home cam's edge.
    shell.step(&["enable", "x"], false);
    let out = shell.step(HOME, true);
    assert!(out.contains(&stands_at(NORMAL_POSITION)), "{out}");
    let edge = shell.reference_count();
    eprintln!(
        "MoveHome: reference at count {edge:.3} (the cam's edge: {})",
        CAM.0
    );
    assert!((edge - CAM.0 as f64).abs() <= 1.0 + 1e-6, "{edge}");

    // 3. Below the cam, the drive homes itself on the same edge with the method given.
    shell.step(&["move", "x", "--to=-5", "--speed", "50"], true);
    let out = shell.step(&["home", "x", "--drive", "--method", "19"], true);
    assert!(
        out.contains(&format!(
            "x: homed by its drive; stands at {:.3}",
            -HOME_OFFSET_MM
        )),
        "{out}"
    );
    let home_offset = shell.sdo_i32("0x607C:0");
    assert!(
        (home_offset as f64 - HOME_OFFSET_MM * COUNTS_PER_MM).abs() <= 1.0,
        "0x607C = {home_offset}"
    );
    // Handed back in CSP (0x6061 is not in the csp-minimal process data: read by SDO).
    assert_eq!(
        shell
            .ok(&["sdo", "upload", "--axis", "x", "0x6061:0", "--type", "i8"])
            .trim(),
        "8"
    );
    let x = shell.axis("x");
    assert_eq!(x["homed"], true, "{x}");
    // The drive's frame: its home (the edge) reads minus the home offset; the actual
    // within the drive's standstill hold of it.
    let p = x["position"].as_f64().unwrap();
    assert!((p * COUNTS_PER_MM + home_offset as f64).abs() <= 4.0, "{x}");
    // A move in the drive's frame, to below the cam.
    let out = shell.step(&["move", "x", "--to=-9", "--speed", "50"], true);
    assert!(out.contains("x: "), "{out}");
    let p = shell.axis("x")["position"].as_f64().unwrap();
    assert!((p + 9.0).abs() < 0.01, "{p}");
    // MoveHome with its last parameters finds the edge where the drive homed: at minus
    // the home offset in the drive's counts, to one count.
    let out = shell.step(&["home", "x"], true);
    assert!(out.contains(&stands_at(NORMAL_POSITION)), "{out}");
    let edge = shell.reference_count();
    eprintln!("MoveHome after drive homing: reference at count {edge:.3} (0x607C = {home_offset})");
    assert!((edge + home_offset as f64).abs() <= 1.0 + 1e-6, "{edge}");
    shell.settle(true);
    let (out, records, first) = run.stop(&shell, started);
    assert!(
        out.contains(&format!("saved axis parameters in {}", state.display())),
        "{out}"
    );
    let config = gantry::config::Config::load(&dir.join("gantry.toml").display().to_string())
        .expect("the configuration");
    // The drive of `x` (the test drives no other axis; the invariant needs a drive that
    // took targets).
    let drives: Vec<DriveUnderTest> = DriveUnderTest::of_config(&config)
        .into_iter()
        .filter(|d| d.axis == "x")
        .collect();
    assert_eq!(drives.len(), 1);
    let conditions = TestConditions {
        injects_following_error: false,
        phase_locked: false,
    };
    let cycle_s = f64::from(config.bus.cycle_us) * 1e-6;
    assert_record_invariants(&records, &drives, cycle_s, conditions);

    // 4. Both started again: the simulated drive powers up with its commutation setting 0
    // and its position at 0; gantry writes the saved offset back before anything enables
    // the axis, and MoveHome runs with the saved parameters.
    let run = start(&pair, &dir, 2);
    shell.socket = run.socket.clone();
    let restarted = shell.frames();
    assert_eq!(shell.sdo_i32("0x2100:0"), written);
    assert_eq!(shell.axis("x")["homed"], false);
    shell.step(&["enable", "x"], false);
    let out = shell.step(&["home", "x"], true);
    assert!(out.contains(&stands_at(NORMAL_POSITION)), "{out}");
    let edge = shell.reference_count();
    eprintln!("after the restart: reference at count {edge:.3}");
    assert!((edge - CAM.0 as f64).abs() <= 1.0 + 1e-6, "{edge}");
    let out = shell.step(&["move", "x", "--to", "20", "--speed", "50"], true);
    assert!(out.contains("x: "), "{out}");
    shell.settle(true);
    let (out, records, second) = run.stop(&shell, restarted);
    // Frames lost over both runs (from the first command on): replies later than the next
    // cycle's start, from this VM's stalls. Measured 0.2-1.7 % of the cycles while other
    // builds ran (plain moves in `veth_service.rs` lose under 1 %); an exchange that is
    // broken, not late now and then, loses far more than the 3 % allowed.
    let (cycles, lost) = (first.cycles + second.cycles, first.lost + second.lost);
    eprintln!("frames lost: {lost} in {cycles} cycles");
    assert!(
        lost * 100 <= 3 * cycles,
        "{lost} frames lost in {cycles} cycles ({first:?}, {second:?})"
    );
    assert!(
        out.contains(&format!(
            "axis x: commutation offset {written} counts written to its drive (0x2100:00) \
             from the saved parameters"
        )),
        "{out}"
    );
    assert_record_invariants(&records, &drives, cycle_s, conditions);
    eprintln!(
        "veth commissioning and homing: {:.1} s, timing stops (reset, command repeated): {} {:?}",
        began.elapsed().as_secs_f64(),
        shell.stops.len(),
        shell.stops
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
