//! `gantry-sim`: the simulated EtherCAT network as its own process, answering on a
//! network interface (e.g. one end of a veth pair) in real time.
//!
//! ```text
//! gantry-sim --interface veth-sim --config sim.toml [--seconds 10] [--priority 80]
//! ```

use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Parser;
use gantry_sim::config::SimConfig;
use gantry_sim::realtime::WallClock;
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

fn run(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    let config = SimConfig::load(&args.config)?;
    let mut chain = config.chain()?;
    let socket = RawSocket::open(&args.interface)?;
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
    loop {
        if end.is_some_and(|end| Instant::now() >= end) {
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
                }
                // A real network drops what it cannot parse; so do we, and count it.
                Err(_) => dropped += 1,
            }
        }
        // After a stall the applications catch up a few periods, not all of it.
        clock.catch_up(&mut chain);
    }
    println!("gantry-sim: served {served} frames, dropped {dropped} malformed");
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
