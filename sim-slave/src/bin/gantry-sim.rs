//! `gantry-sim`: the simulated EtherCAT network as its own process, answering on a
//! network interface (e.g. one end of a veth pair) in real time.
//!
//! ```text
//! gantry-sim --interface veth-sim --config sim.toml [--seconds 10] [--priority 80]
//! ```
//!
//! On SIGTERM or SIGINT (or after `--seconds`) it prints a summary and exits: frames
//! served and dropped, and the largest gaps the drives saw — between frames, and per
//! slave between writes of its process data (its watchdog and setpoints depend on them).

use std::io::Write;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use clap::Parser;
use gantry_sim::config::SimConfig;
use gantry_sim::realtime::{Gaps, WallClock};
use gantry_sim::transport::raw_socket::RawSocket;

/// The simulated EtherCAT network on a network interface.
#[derive(Parser, Debug)]
#[command(name = "gantry-sim", version)]
struct Args {
    /// Network interface to answer on (the master sends on the other end of the wire).
    #[arg(long)]
    interface: String,
    /// TOML file that lists the chain.
    #[arg(long)]
    config: String,
    /// Stop after this many seconds (default: run until killed).
    #[arg(long)]
    seconds: Option<f64>,
    /// Run under SCHED_FIFO at this priority (1–99; needs CAP_SYS_NICE).
    #[arg(long)]
    priority: Option<i32>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gantry-sim: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Set by SIGTERM/SIGINT: finish the loop and print the summary.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::Relaxed);
}

/// SIGTERM and SIGINT end the run with its summary (the wait for a frame is cut short:
/// `ppoll` returns EINTR, which the socket reports as no frame).
fn catch_signals() {
    let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
    // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
    unsafe {
        libc::signal(libc::SIGTERM, handler);
        libc::signal(libc::SIGINT, handler);
    }
}

fn run(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    let config = SimConfig::load(&args.config)?;
    let mut chain = config.chain()?;
    let socket = RawSocket::open(&args.interface)?;
    catch_signals();
    if let Some(priority) = args.priority {
        set_fifo(priority)?;
    }
    println!(
        "gantry-sim: {} slaves on {}, applications every {} µs",
        chain.slaves().len(),
        args.interface,
        config.cycle_us
    );
    let period = Duration::from_micros(u64::from(config.cycle_us));
    let start = Instant::now();
    let end = args
        .seconds
        .map(|s| start + Duration::from_secs_f64(s.max(0.0)));
    // The chain's clocks follow this host's; its applications run every period.
    let clock = WallClock::start(&chain, period);
    let mut buf = vec![0u8; 9100];
    let (mut served, mut dropped) = (0u64, 0u64);
    let mut gaps = Gaps::new(chain.slaves().len());
    loop {
        if STOP.load(Ordering::Relaxed) || end.is_some_and(|end| Instant::now() >= end) {
            break;
        }
        let wait = clock.until_next_period(&chain);
        if let Some(n) = socket.recv(&mut buf, Some(wait))? {
            let frame = buf.get_mut(..n).unwrap_or_default();
            clock.catch_up(&mut chain);
            match chain.process(frame) {
                Ok(()) => {
                    socket.send(frame)?;
                    served += 1;
                    gaps.frame(Instant::now(), &chain);
                }
                // A real network drops what it cannot parse; so do we, and count it.
                Err(_) => dropped += 1,
            }
        }
        // After a stall the applications catch up a few periods, not all of it.
        clock.catch_up(&mut chain);
    }
    // Whoever started us may have stopped reading: a summary nobody reads is no error.
    let _ = writeln!(
        std::io::stdout(),
        "gantry-sim: served {served} frames, dropped {dropped} malformed; {gaps}"
    );
    Ok(())
}

/// SCHED_FIFO at `priority` and memory locked, as the master's RT thread does.
fn set_fifo(priority: i32) -> Result<(), String> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: plain syscalls on this process with a valid parameter block.
    unsafe {
        if libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) != 0 {
            return Err(format!(
                "SCHED_FIFO priority {priority}: {} (needs CAP_SYS_NICE)",
                std::io::Error::last_os_error()
            ));
        }
        if libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) != 0 {
            return Err(format!(
                "mlockall: {} (needs CAP_IPC_LOCK)",
                std::io::Error::last_os_error()
            ));
        }
    }
    Ok(())
}
