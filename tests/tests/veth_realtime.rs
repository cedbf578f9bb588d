//! Real time, two processes: gantry's engine — `Engine::run` in a real-time cycle thread
//! (`gantry::service::start_cycle`: SCHED_FIFO 80, memory locked, PM QoS; LateReply::Lost;
//! phase-locked to SYNC0), as
//! `gantry run` runs it — in this process, and `gantry-sim` as its own process, on the two
//! ends of a veth pair in two network namespaces. Four CiA-402 servos at 1 kHz for 10 s,
//! each moving back and forth the whole time through the controller; the test reports the
//! engine's cycle figures (wake-up latency, compute, bus round trip, overruns), the frames
//! lost, the largest following error, and the largest gaps the drives saw between
//! process-data writes.
//!
//! Needs root for the namespaces; `deploy/test.sh` runs it (`--include-ignored`).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

use gantry::runtime::controller::{CommandHandle, Controller};
use gantry::runtime::cycle::COMMUNICATION_FAULT;
use gantry::runtime::protocol::TraceSample;
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::status::AxisFault;
use gantry_sim::plant::servo::ERROR_SYNC_WATCHDOG;
use gantry_tests::invariant::{assert_record_invariants, DriveUnderTest, TestConditions};
use gantry_tests::netns::{start_gantry_sim_recording, VethPair};

const DRIVES: usize = 4;
const PERIOD_NS: u64 = 1_000_000;
const SECONDS: u64 = 10;

/// The drives tolerate about ten missed SYNC0 periods (0x10F1:02 = 32, as the examples'
/// drives and the other real-time tests on this project's VMs without PREEMPT_RT, whose
/// threads stall for milliseconds: with the shipped 4 a fresh-clone CI run here stopped
/// seven times in 10 s and one axis made 8 of the 10 moves asked); the strict limit is the
/// lockstep tests'.
const SIM_CONFIG: &str = r#"
cycle_us = 1000
[[slave]]
kind = "servo"
[slave.al]
sync_error_limit = 32
[[slave]]
kind = "servo"
start_position = 100000
[slave.al]
sync_error_limit = 32
[[slave]]
kind = "servo"
start_position = -250000
[slave.al]
sync_error_limit = 32
[[slave]]
kind = "servo"
bandwidth_hz = 150
[slave.al]
sync_error_limit = 32
"#;
/// The master's configuration: the example's bus and real-time settings on this pair.
fn gantry_config(interface: &str) -> String {
    let mut text = format!(
        "[bus]\nkind = \"ethercat\"\ninterface = {interface:?}\ncycle_us = 1000\ndc = true\n\
         [rt]\npriority = 80\nlock_memory = true\noverrun_limit = 10\n"
    );
    for i in 0..DRIVES {
        text += &format!(
            "[[axis]]\nname = \"a{i}\"\ndrive = {i}\n\
             scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
             max = {{ speed = 250.0, acceleration = 2500.0, jerk = 50000.0 }}\n\
             defaults = {{ speed = 200.0, acceleration = 2000.0, deceleration = 2000.0, \
             jerk = 40000.0, ramp = \"scurve\" }}\n"
        );
    }
    text
}

/// What the cycle thread hands back at the end.
#[derive(Debug)]
struct Ended {
    lost: u64,
    wkc_errors: u64,
}

#[test]
#[ignore = "needs root (network namespaces) and the gantry-sim binary; deploy/test.sh runs it"]
fn four_drives_at_1khz_for_10_s_over_veth_through_the_engine() {
    let pair = VethPair::create("rt").expect("veth pair in two namespaces");
    let dir = std::env::temp_dir().join(format!("gantry-veth-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let sim_path = dir.join("sim.toml");
    std::fs::write(&sim_path, SIM_CONFIG).unwrap();
    let records = dir.join("drive-records.json");
    let sim = start_gantry_sim_recording(
        &pair.sim_ns,
        &pair.sim_if,
        &sim_path,
        DRIVES,
        Some(&records),
    );
    let config =
        gantry::config::Config::parse(&gantry_config(&pair.master_if), "veth-realtime.toml")
            .expect("valid configuration");
    gantry::runtime::rt::check(&config.rt, true).expect("root may run in real time");

    // The cycle thread, as `gantry run` makes it.
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    let cycle_thread = {
        let (stop, config) = (stop.clone(), config.clone());
        let netns = format!("/run/netns/{}", pair.master_ns);
        std::thread::Builder::new()
            .name("gantry-cycle".into())
            .spawn(move || -> Result<Ended, String> {
                let ns = std::fs::File::open(&netns).map_err(|e| e.to_string())?;
                nix::sched::setns(ns, nix::sched::CloneFlags::CLONE_NEWNET)
                    .map_err(|e| e.to_string())?;
                // Real time, bring-up and engine exactly as `gantry run` makes them.
                let (engine, ends) = gantry::service::start_cycle(
                    &config,
                    true,
                    &gantry::ethercat::link::InterfaceOnly,
                    &mut std::io::sink(),
                )
                .map_err(|e| gantry::error_chain::Chain(&e).to_string())?;
                tx.send(ends).map_err(|e| e.to_string())?;
                let engine = engine.run(PERIOD_NS, &stop);
                let counters = gantry::runtime::bus::CycleBus::counters(&engine.bus);
                let ended = Ended {
                    lost: counters.lost,
                    wkc_errors: counters.incomplete,
                };
                engine.into_bus().shut_down(&mut std::io::sink());
                Ok(ended)
            })
            .unwrap()
    };
    let Ok(ends) = rx.recv_timeout(Duration::from_secs(30)) else {
        panic!("bring-up: {:?}", cycle_thread.join());
    };
    let ctl = Controller::new(ends, (0..DRIVES).map(|i| format!("a{i}")).collect());

    // The application: enable, call the position 0, then move each axis back and forth.
    let wait = |h: CommandHandle| {
        h.wait(Duration::from_secs(5)).unwrap_or_else(|e| {
            let s = ctl.snapshot();
            panic!(
                "{e}: cycle {} drives {:?} axes {:?}",
                s.cycle, s.drives, s.axes
            )
        })
    };
    for i in 0..DRIVES {
        let enabled = wait(
            ctl.command(i, Command::Power(PowerCommand::Enable))
                .unwrap(),
        );
        let s = ctl.snapshot();
        assert_eq!(
            enabled,
            CommandStatus::Done,
            "axis {i}: {:?}, drive {:?}",
            s.axes[i].error,
            s.drives[i]
        );
        let home = Command::SetPosition {
            position: 0.0,
            relative: false,
        };
        assert_eq!(wait(ctl.command(i, home).unwrap()), CommandStatus::Done);
    }
    let mut trace: Vec<TraceSample> = Vec::with_capacity(20_000);
    ctl.drain_trace(&mut trace);
    trace.clear();
    let mut moves: [Option<CommandHandle>; DRIVES] = Default::default();
    let mut done = [0u32; DRIVES];
    // Moves that ended otherwise than Done, with the axis' error then; and every reason
    // the bus gave for stopping an axis.
    let mut stops = Vec::new();
    let mut reasons = std::collections::BTreeSet::new();
    let end = Instant::now() + Duration::from_secs(SECONDS);
    let mut max_following_mm = 0.0f64;
    let mut samples = Vec::with_capacity(1024);
    while Instant::now() < end {
        for (i, slot) in moves.iter_mut().enumerate() {
            let start = match slot.as_ref().map(CommandHandle::status) {
                None => true,
                Some(Some(CommandStatus::Done)) => {
                    done[i] += 1;
                    true
                }
                Some(Some(s)) if s.is_final() => {
                    // The axis stopped: record why, reset it as an operator would, and
                    // go on (a drive that lost power needs enabling again).
                    let snap = ctl.snapshot();
                    if let Some(f) = snap.drives[i].bus_fault {
                        reasons.insert(f.to_string());
                    }
                    stops.push((i, s, snap.axes[i].error));
                    std::thread::sleep(Duration::from_millis(20));
                    let _ = ctl.reset(i).map(|h| h.wait(Duration::from_secs(2)));
                    std::thread::sleep(Duration::from_millis(20));
                    let enable = Command::Power(PowerCommand::Enable);
                    let _ = ctl
                        .command(i, enable)
                        .map(|h| h.wait(Duration::from_secs(2)));
                    true
                }
                // Queued, busy or active.
                Some(_) => false,
            };
            if start {
                let to = if done[i] % 2 == 0 {
                    20.0 + 5.0 * i as f64
                } else {
                    -10.0
                };
                let cmd = Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, to));
                *slot = Some(ctl.command(i, cmd).unwrap());
            }
        }
        for d in &ctl.snapshot().drives {
            if let Some(f) = d.bus_fault {
                reasons.insert(f.to_string());
            }
        }
        samples.clear();
        ctl.drain_trace(&mut samples);
        for s in &samples {
            for i in 0..DRIVES {
                max_following_mm = max_following_mm.max((s.set[i] - s.actual[i]).abs());
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    stop.store(true, Ordering::Relaxed);
    let ended = cycle_thread.join().unwrap().expect("the cycle thread");
    let gaps = sim.stop().expect("gantry-sim's summary");
    // The percentiles are computed on the application's side, from every cycle.
    let f = ctl.figures();
    eprintln!(
        "veth, {DRIVES} drives, 1 kHz, gantry's engine (SCHED_FIFO 80, LateReply::Lost, \
         phase lock), {} cycles:\n  wake-up latency {}\n  compute         {}\n  bus round trip  \
         {}\n  overruns {} (longest run {}), lost frames {}, wrong working counters {}\n  \
         moves done {done:?}, largest following error {max_following_mm:.3} mm\n  \
         axes stopped {} times: {stops:?}, reasons {reasons:?}\n  {}",
        f.cycles,
        f.wake,
        f.compute,
        f.round_trip,
        f.overruns,
        f.worst_overrun_run,
        ended.lost,
        ended.wkc_errors,
        stops.len(),
        gaps.line
    );
    // What reached the drives: never a target step beyond the axis' speed per master
    // cycle, never a following-error fault. Setpoints are missed or doubled here now and
    // then (this VM's stalls): the drives count them, the test reports them above.
    assert_record_invariants(
        &records,
        &DriveUnderTest::of_config(&config),
        PERIOD_NS as f64 * 1e-9,
        TestConditions {
            injects_following_error: false,
            phase_locked: false,
        },
    );
    std::fs::remove_dir_all(&dir).unwrap();
    // Generous bounds: this is a shared VM whose kernel does not preempt (an RT thread
    // waits for kernel work of other tasks on its CPU: 2–10 ms measured), so frames are
    // lost now and then, three in a row at times, which stops the axes (the example's
    // limit); two SYNC0 periods without outputs and the drives themselves leave Op (their
    // sync error, 0x10F1:02), which stops them too. The figures above are the result;
    // what must hold is that every stop was one of these two (never a wrong working
    // counter, a following error or a drive fault of another kind), and that the
    // exchange is right when frames arrive.
    // The axis' error names whichever the master saw first: the bus (0x8100), or the
    // drive's own fault for its sync error (0x8700, in its inputs, valid in SafeOp) when
    // that came in the same frame as the AL-status BRD that shows the slave left OP.
    for (axis, status, error) in &stops {
        assert!(
            matches!(
                error,
                Some(AxisFault::Drive {
                    code: COMMUNICATION_FAULT | ERROR_SYNC_WATCHDOG
                })
            ),
            "axis {axis} stopped ({status:?}) by something else than the bus or the drive's \
             sync error: {error:?}; {stops:?}"
        );
    }
    for reason in &reasons {
        assert!(
            reason.contains("frames lost in a row")
                || reason.contains("left OP: now Safe-Operational"),
            "{reasons:?}"
        );
    }
    assert_eq!(ended.wkc_errors, 0, "every working counter was right");
    assert!(
        ended.lost * 100 <= f.cycles,
        "{} frames lost in {} cycles",
        ended.lost,
        f.cycles
    );
    for (i, n) in done.iter().enumerate() {
        assert!(*n >= 10, "axis {i} moved back and forth: {n} moves");
    }
    // 0.3–1 mm in a quiet run (servo lag plus a cycle's transport at 200 mm/s); a stall of
    // the simulator's process longer than four periods skips plant time, so this VM's
    // 5–10 ms stalls can add a few mm. A broken exchange gives tens.
    assert!(
        max_following_mm < 5.0,
        "following error {max_following_mm} mm"
    );
    assert!(
        f.overruns < f.cycles / 4,
        "overruns {} of {}",
        f.overruns,
        f.cycles
    );
    assert!(
        f.cycles >= SECONDS * 900,
        "{} cycles in {SECONDS} s",
        f.cycles
    );
}
