//! Runs a cycle thread under a seccomp filter that kills the process on any `futex` call
//! (see `gantry_tests::seccomp`), for `tests/runtime_no_lock.rs`. Modes:
//!
//! - `engine`: gantry's cycle thread as `gantry run` starts it (`service::start_cycle`:
//!   SCHED_FIFO, memory locked, late replies lost at the deadline) on the in-process
//!   simulator, 4 axes at 1 kHz; filtered from the first cycle of `Engine::run` (its
//!   clock, the phase lock to SYNC0, the shutdown) for about 3 s while the application
//!   hammers it (moves, resets, status, trace) and the bus loses frames and a drive's
//!   cable is pulled, the slave drops out of OP, and a reset brings it back. Prints what
//!   ran and which threads run in real time, and exits 0 — unless the kernel killed it
//!   first.
//! - `canopen`: the CANopen cycle (`Engine::cycle` on a `CanopenBus`: RPDOs, SYNC,
//!   TPDOs, heartbeats — the nodes' and gantry's own —, EMCYs, the restore's NMT and SDO
//!   steps) in lockstep on four simulated drives behind a link that takes no lock
//!   (`gantry_tests::can_lockfree`), filtered from the first cycle for ~3 s of the
//!   application's moves and resets, while a node's heartbeat is lost (its axis stops)
//!   and another node is reset by another master, both brought back by resets inside the
//!   filtered cycles. Needs no root (no real-time scheduling: lockstep time).
//! - `contended-lock`, `parking`: the filtered thread waits on a held `Mutex`, or in
//!   `futures_lite::block_on` (a parker): both must be killed, which shows the filter
//!   catches what it is meant to.

use gantry::runtime::bus::CycleBus;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Mutex, OnceLock};
use std::task::{Poll, Waker};
use std::time::Duration;

use gantry::runtime::controller::Controller;
use gantry::runtime::sdo::{SdoData, SdoRequest};
use gantry::service::{start_cycle, CYCLE_STACK_BYTES, CYCLE_THREAD};
use gantry_cli::simulator::{SimLink, Simulator};
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_tests::seccomp::forbid_futex_in_this_thread;

const AXES: usize = 4;
/// Rounds of the application's scenario, 60 ms each.
const ROUNDS: u32 = 50;
/// Bus time of a CANopen round: 200 cycles of 2 ms (a move of the round ends in it).
const ROUND_NS: u64 = 400_000_000;

static FILTERED: AtomicBool = AtomicBool::new(false);
static FINISHED: AtomicBool = AtomicBool::new(false);
static LOST_FRAMES: AtomicU64 = AtomicU64::new(0);
static CYCLES: AtomicU64 = AtomicU64::new(0);
static STOP: AtomicBool = AtomicBool::new(false);

fn main() {
    let mode = std::env::args().nth(1).unwrap_or_default();
    match mode.as_str() {
        "engine" => engine(),
        "canopen" => canopen(),
        "contended-lock" => contended_lock(),
        "parking" => parking(),
        other => {
            eprintln!(
                "cycle-under-seccomp: unknown mode {other:?} (engine, canopen, contended-lock, \
                 parking)"
            );
            std::process::exit(2);
        }
    }
}

/// Sleeps until the process exits: the filtered thread must not return, since ending a
/// thread may free memory under malloc's locks.
fn park_forever() -> ! {
    loop {
        std::thread::sleep(Duration::from_secs(3600));
    }
}

fn wait_for(flag: &AtomicBool, what: &str) {
    for _ in 0..30_000 {
        if flag.load(Ordering::Acquire) {
            return;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    eprintln!("cycle-under-seccomp: timed out waiting for {what}");
    std::process::exit(3);
}

fn engine() {
    let mut config = gantry_tests::sim_config(AXES, 1000);
    // This test is about the cycle thread, not about riding through lost frames
    // (`bus_faults`, `claim_*` test the limit): on this project's non-preemptible VMs a
    // real-time thread now and then waits milliseconds, three frames in a row are lost
    // and the example's limit would stop the axes it exercises.
    config.bus.faults.lost_frames_limit = 50;
    let (tx, rx) = mpsc::channel();
    let spawned = std::thread::Builder::new()
        .name(CYCLE_THREAD.into())
        .stack_size(CYCLE_STACK_BYTES)
        .spawn(move || {
            // As `gantry run` starts its cycle thread: SCHED_FIFO, memory locked, the bus
            // (and its pump) brought up from it, late replies lost at the deadline.
            let simulator = Simulator::new(SimLink::Thread);
            let (engine, ends) = start_cycle(&config, true, &simulator, &mut std::io::sink())
                .unwrap_or_else(|e| {
                    eprintln!("start: {}", gantry::error_chain::Chain(&e));
                    std::process::exit(4)
                });
            let dc = engine.bus().ethercat().is_some_and(|bus| bus.dc().active);
            let _ = tx.send((ends, simulator.chain(), dc));
            // From the first cycle of Engine::run to its end (the shutdown included).
            if let Err(e) = forbid_futex_in_this_thread() {
                eprintln!("seccomp: {e}");
                std::process::exit(5);
            }
            FILTERED.store(true, Ordering::Release);
            let engine = engine.run(1_000_000, &STOP);
            LOST_FRAMES.store(engine.bus.counters().lost, Ordering::Relaxed);
            CYCLES.store(engine.counters().cycles, Ordering::Relaxed);
            FINISHED.store(true, Ordering::Release);
            park_forever();
        });
    if let Err(e) = spawned {
        eprintln!("the cycle thread: {e}");
        std::process::exit(4);
    }
    let Ok((ends, chain, dc)) = rx.recv() else {
        eprintln!("the cycle thread ended at start");
        std::process::exit(4);
    };
    let Some(chain) = chain else {
        eprintln!("no simulated chain");
        std::process::exit(4);
    };
    let ctl = Controller::new(ends, (0..AXES).map(|i| format!("a{i}")).collect());
    for i in 0..AXES {
        let _ = ctl.command(i, Command::Power(PowerCommand::Enable));
        let _ = ctl.command(
            i,
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
        );
    }
    wait_for(&FILTERED, "the filter");
    let (mut handles, mut resets, mut snapshots) = (Vec::new(), Vec::new(), 0u64);
    let mut trace = Vec::new();
    // SDO transfers beside the process data: started each round, their outcomes taken.
    let (mut transfers, mut sdo_started, mut sdo_ended, mut sdo_ok) = (Vec::new(), 0, 0, 0);
    for round in 1..=ROUNDS {
        for i in 0..AXES {
            let to = if round % 2 == 0 { 5.0 } else { 0.0 };
            let m = MovePtp::new(PositioningMode::AbsNormal, to);
            if let Ok(h) = ctl.command(i, Command::MovePtp(m)) {
                handles.push(h);
            }
        }
        match round % 10 {
            // Frames lost (fewer in a row than the limit: ridden through).
            3 => {
                if let Ok(mut c) = chain.lock() {
                    c.drop_frames(2);
                }
            }
            // The cable behind drive 2 pulled for longer than its watchdog: its axes
            // stop, the slave drops to SafeOp; plugged back and reset (the recovery's
            // register accesses run in the filtered cycles).
            6 => {
                if let Ok(mut c) = chain.lock() {
                    c.cut_before(Some(2));
                }
            }
            8 => {
                if let Ok(mut c) = chain.lock() {
                    c.cut_before(None);
                }
                for i in 0..AXES {
                    if let Ok(h) = ctl.reset(i) {
                        resets.push(h);
                    }
                    let _ = ctl.command(i, Command::Power(PowerCommand::Enable));
                }
            }
            _ => {}
        }
        let drive = round as usize % AXES;
        let value = SdoData::new(&[8]);
        for request in [
            SdoRequest::upload(drive, 0x1018, 1),
            SdoRequest::download(drive, 0x6060, 0, value),
        ] {
            if let Ok(h) = ctl.sdo(request) {
                transfers.push(h);
                sdo_started += 1;
            }
        }
        // Read the status and the trace as fast as an eager client would.
        let until = std::time::Instant::now() + Duration::from_millis(60);
        while std::time::Instant::now() < until {
            std::hint::black_box(ctl.snapshot());
            snapshots += 1;
            ctl.drain_trace(&mut trace);
            trace.clear();
            transfers.retain(|h| match h.outcome() {
                Some(r) => {
                    sdo_ended += 1;
                    sdo_ok += u32::from(r.is_ok());
                    false
                }
                None => true,
            });
        }
    }
    STOP.store(true, Ordering::Relaxed);
    wait_for(&FINISHED, "the end of Engine::run");
    let done = |hs: &[gantry::runtime::controller::CommandHandle]| {
        hs.iter()
            .filter(|h| h.status() == Some(CommandStatus::Done))
            .count()
    };
    // The real-time threads of the process, and whether async-io's reactor ever started.
    let threads = gantry_tests::threads::threads();
    let mut real_time: Vec<String> = threads
        .iter()
        .filter(|t| t.real_time())
        .map(|t| t.name.clone())
        .collect();
    real_time.sort();
    let reactor = threads.iter().any(|t| t.name == "async-io");
    println!(
        "cycles {}; moves {} done {}; resets {} done {}; snapshots {snapshots}; \
         lost frames {}; dc {dc}; real-time threads [{}]; async-io reactor {reactor}; \
         sdo {sdo_started} ended {sdo_ended} ok {sdo_ok}",
        CYCLES.load(Ordering::Relaxed),
        handles.len(),
        done(&handles),
        resets.len(),
        done(&resets),
        LOST_FRAMES.load(Ordering::Relaxed),
        real_time.join(" "),
    );
    std::process::exit(0);
}

static HEARTBEATS: AtomicU64 = AtomicU64::new(0);
static EXCHANGES: AtomicU64 = AtomicU64::new(0);

fn canopen() {
    use gantry::canopen::CanopenBus;
    use gantry::runtime::clock::StepClock;
    use gantry::runtime::cycle::Cycle;
    use gantry::runtime::engine::Engine;
    use gantry_tests::can_lockfree::LockFreeLink;
    use gantry_tests::can_rig::{can_config_with, servos};

    const NODES: [u8; 4] = [1, 2, 3, 4];
    // With a SYNC counter: its count and the restore's 0x1019 write run filtered too.
    let config = can_config_with(&NODES, 2000, "csp", "sync_counter = 16");
    let (link, control) = LockFreeLink::new(servos(&NODES));
    let (tx, rx) = mpsc::channel();
    let steer = control.clone();
    let spawned = std::thread::Builder::new()
        .name(CYCLE_THREAD.into())
        .stack_size(CYCLE_STACK_BYTES)
        .spawn(move || {
            let bus = CanopenBus::bring_up_on(&config, Box::new(link), &mut std::io::sink())
                .unwrap_or_else(|e| {
                    eprintln!("bus up: {}", gantry::error_chain::Chain(&e));
                    std::process::exit(4)
                });
            let cycle = Cycle::from_config(&config, &bus).unwrap_or_else(|e| {
                eprintln!("the cycle: {}", gantry::error_chain::Chain(&e));
                std::process::exit(4)
            });
            let start = bus.link().now_ns();
            let (mut engine, ends) = Engine::new(bus, cycle, config.rt.overrun_limit, 1024);
            steer.clock_ns.store(start, Ordering::Release);
            steer.stepped.store(true, Ordering::Release);
            let moved = steer.clone();
            let mut clock = StepClock::new(2_000_000, start, move |to: u64| {
                moved.clock_ns.store(to, Ordering::Release)
            });
            let _ = tx.send(ends);
            if let Err(e) = forbid_futex_in_this_thread() {
                eprintln!("seccomp: {e}");
                std::process::exit(5);
            }
            FILTERED.store(true, Ordering::Release);
            // Lockstep: each cycle at once, the step clock moving the bus' time.
            while !STOP.load(Ordering::Relaxed) {
                if !engine.cycle(&mut clock) {
                    break;
                }
            }
            CYCLES.store(engine.counters().cycles, Ordering::Relaxed);
            HEARTBEATS.store(engine.bus.heartbeats_sent(), Ordering::Relaxed);
            EXCHANGES.store(engine.bus.exchanges(), Ordering::Relaxed);
            FINISHED.store(true, Ordering::Release);
            park_forever();
        });
    if let Err(e) = spawned {
        eprintln!("the cycle thread: {e}");
        std::process::exit(4);
    }
    let Ok(ends) = rx.recv() else {
        eprintln!("the cycle thread ended at start");
        std::process::exit(4);
    };
    let ctl = Controller::new(ends, (0..AXES).map(|i| format!("a{i}")).collect());
    let enable = |ctl: &Controller| {
        for i in 0..AXES {
            let _ = ctl.command(i, Command::Power(PowerCommand::Enable));
        }
    };
    enable(&ctl);
    for i in 0..AXES {
        let _ = ctl.command(
            i,
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
        );
    }
    wait_for(&FILTERED, "the filter");
    let (mut handles, mut resets, mut snapshots) = (Vec::new(), Vec::new(), 0u64);
    let mut trace = Vec::new();
    for round in 1..=ROUNDS {
        for i in 0..AXES {
            let to = if round % 2 == 0 { 5.0 } else { 0.0 };
            let m = MovePtp::new(PositioningMode::AbsNormal, to);
            if let Ok(h) = ctl.command(i, Command::MovePtp(m)) {
                handles.push(h);
            }
        }
        match round % 10 {
            // Node 2's heartbeat lost (its cable): its axis stops past the consumer time.
            3 => control.drop.store(0x702, Ordering::Relaxed),
            // Node 4 reset by another master: boot-up, its axis stops.
            6 => control.reset_node.store(4, Ordering::Relaxed),
            // Plugged back; resets bring both nodes back (NMT, SDO) inside the filter.
            8 => {
                control.drop.store(0, Ordering::Relaxed);
                for i in 0..AXES {
                    if let Ok(h) = ctl.reset(i) {
                        resets.push(h);
                    }
                }
            }
            9 => enable(&ctl),
            _ => {}
        }
        // Each round lasts the same bus time whatever the host's load (the cycles run
        // as fast as the host lets them; a wall-clock round made the moves' outcome
        // depend on it).
        let round_end = control.clock_ns.load(Ordering::Acquire) + ROUND_NS;
        let give_up = std::time::Instant::now() + Duration::from_secs(60);
        while control.clock_ns.load(Ordering::Acquire) < round_end {
            if FINISHED.load(Ordering::Acquire) || std::time::Instant::now() > give_up {
                eprintln!("the cycle thread stopped cycling in round {round}");
                std::process::exit(6);
            }
            std::hint::black_box(ctl.snapshot());
            snapshots += 1;
            ctl.drain_trace(&mut trace);
            trace.clear();
        }
    }
    STOP.store(true, Ordering::Relaxed);
    wait_for(&FINISHED, "the end of the cycles");
    let done = |hs: &[gantry::runtime::controller::CommandHandle]| {
        hs.iter()
            .filter(|h| h.status() == Some(CommandStatus::Done))
            .count()
    };
    println!(
        "cycles {}; exchanges {}; moves {} done {}; resets {} done {}; snapshots \
         {snapshots}; boot-ups {}; gantry heartbeats {}; queue overflow {}",
        CYCLES.load(Ordering::Relaxed),
        EXCHANGES.load(Ordering::Relaxed),
        handles.len(),
        done(&handles),
        resets.len(),
        done(&resets),
        control.boot_ups.load(Ordering::Relaxed),
        HEARTBEATS.load(Ordering::Relaxed),
        control.overflow.load(Ordering::Relaxed),
    );
    std::process::exit(0);
}

fn contended_lock() {
    static LOCK: Mutex<u32> = Mutex::new(0);
    let held = LOCK.lock();
    std::thread::spawn(|| {
        if forbid_futex_in_this_thread().is_err() {
            std::process::exit(5);
        }
        FILTERED.store(true, Ordering::Release);
        let taken = LOCK.lock();
        println!("took the lock");
        drop(taken);
        FINISHED.store(true, Ordering::Release);
        park_forever();
    });
    wait_for(&FILTERED, "the filter");
    std::thread::sleep(Duration::from_millis(100));
    drop(held);
    wait_for(&FINISHED, "the lock");
    std::process::exit(0);
}

fn parking() {
    // Handed over without a lock: the main thread polls it.
    static WAKER: OnceLock<Waker> = OnceLock::new();
    std::thread::spawn(|| {
        if forbid_futex_in_this_thread().is_err() {
            std::process::exit(5);
        }
        FILTERED.store(true, Ordering::Release);
        // A future that the main thread completes later: block_on parks until then.
        let mut first = true;
        futures_lite::future::block_on(std::future::poll_fn(|cx| {
            if first {
                first = false;
                let _ = WAKER.set(cx.waker().clone());
                Poll::Pending
            } else {
                Poll::Ready(())
            }
        }));
        println!("woke up");
        FINISHED.store(true, Ordering::Release);
        park_forever();
    });
    wait_for(&FILTERED, "the filter");
    for _ in 0..30_000 {
        if let Some(waker) = WAKER.get() {
            std::thread::sleep(Duration::from_millis(100));
            waker.wake_by_ref();
            break;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    wait_for(&FINISHED, "the wake-up");
    std::process::exit(0);
}
