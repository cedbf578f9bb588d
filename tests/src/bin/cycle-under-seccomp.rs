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

static FILTERED: AtomicBool = AtomicBool::new(false);
static FINISHED: AtomicBool = AtomicBool::new(false);
static LOST_FRAMES: AtomicU64 = AtomicU64::new(0);
static CYCLES: AtomicU64 = AtomicU64::new(0);
static STOP: AtomicBool = AtomicBool::new(false);

fn main() {
    let mode = std::env::args().nth(1).unwrap_or_default();
    match mode.as_str() {
        "engine" => engine(),
        "contended-lock" => contended_lock(),
        "parking" => parking(),
        other => {
            eprintln!(
                "cycle-under-seccomp: unknown mode {other:?} (engine, contended-lock, parking)"
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
        let value = SdoData::new(&[8]).unwrap_or_default();
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
