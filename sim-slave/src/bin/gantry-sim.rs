//! `gantry-sim`: the simulated EtherCAT network as its own process, answering on a
//! network interface (e.g. one end of a veth pair) in real time; or, with `--can`, the
//! chain's CANopen nodes on a CAN interface (e.g. vcan0).
//!
//! ```text
//! gantry-sim --interface veth-sim --config sim.toml [--seconds 10] [--priority 80]
//!            [--record records.json]
//! gantry-sim --can vcan0 --config sim.toml [--seconds 10] [--priority 80]
//! gantry-sim eds --config sim.toml --node N --out node.eds
//! ```
//!
//! On CAN every slave needs a node id (`node = N`); each servo becomes a CiA 402 node,
//! the encoder a CiA 406 one, the switch-cam module a CiA 401 one following its servo
//! (`gantry_sim::canopen::CanNetwork`): each boots (boot-up message) when the process
//! starts, answers SDO, NMT, SYNC and RPDOs as they come and runs its timers (heartbeat,
//! event TPDOs, the drive's loops without SYNC) every `cycle_us` of the chain.
//!
//! `gantry-sim eds` writes the electronic data sheet (CiA 306) of the chain's CANopen node
//! `N` (the slave with `node = N`), as a vendor ships one with a device, and exits.
//!
//! On SIGTERM or SIGINT (within one period) or after `--seconds` it prints a summary and
//! exits: frames served and dropped, and the largest gaps the drives saw — between frames,
//! and per slave between writes of its process data (its watchdog and setpoints depend on
//! them). With `--record FILE` it also writes what each drive recorded of the setpoints it took
//! (`gantry_sim::plant::record::DriveRecord`) to FILE as a JSON array, one entry per chain
//! position, `null` for devices that are no drive: the test that started it judges the
//! master by it (`gantry_tests::invariant::assert_record_invariants`).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use clap::Parser;
use gantry_drives::canopen::CanFrame;
use gantry_link::can_socket::{monotonic_ns, CanSocket, CanSocketError};
use gantry_link::raw_socket::RawSocket;
use gantry_sim::canopen::CanNetwork;
use gantry_sim::config::SimConfig;
use gantry_sim::plant::record::write_records;
use gantry_sim::realtime::{Gaps, WallClock};

/// The simulated EtherCAT network on a network interface, or the chain's CANopen nodes on a
/// CAN interface.
#[derive(Parser, Debug)]
#[command(name = "gantry-sim", version)]
#[command(
    after_help = "gantry-sim eds --config FILE --node N --out FILE: the EDS (CiA 306) \
of the chain's CANopen node N"
)]
struct Args {
    /// Network interface to answer on (the master sends on the other end of the wire).
    #[arg(long, required_unless_present = "can", conflicts_with = "can")]
    interface: Option<String>,
    /// CAN interface to simulate the chain's CANopen nodes on (instead of EtherCAT).
    #[arg(long, value_name = "IFACE")]
    can: Option<String>,
    /// TOML file that lists the chain.
    #[arg(long)]
    config: String,
    /// Stop after this many seconds (default: run until killed).
    #[arg(long)]
    seconds: Option<f64>,
    /// Run under SCHED_FIFO at this priority (1–99; needs CAP_SYS_NICE).
    #[arg(long)]
    priority: Option<i32>,
    /// Write the drives' records here (JSON) on exit (EtherCAT only).
    #[arg(long, conflicts_with = "can")]
    record: Option<PathBuf>,
}

/// Set by SIGTERM/SIGINT: the loop ends, the summary is printed and the records are
/// written.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_stop_signal(_: libc::c_int) {
    // Only an atomic store: async-signal-safe.
    STOP.store(true, Ordering::SeqCst);
}

/// SIGTERM and SIGINT set [`STOP`] instead of ending the process.
fn catch_stop_signals() -> Result<(), String> {
    for signal in [libc::SIGTERM, libc::SIGINT] {
        // SAFETY: a zeroed sigaction with a handler that only stores an atomic; the
        // pointers are valid for the call.
        let ok = unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_stop_signal as *const () as libc::sighandler_t;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut()) == 0
        };
        if !ok {
            return Err(format!(
                "signal {signal}: {}",
                std::io::Error::last_os_error()
            ));
        }
    }
    Ok(())
}

/// `gantry-sim eds`: the EDS of one node of the chain.
#[derive(Parser, Debug)]
#[command(name = "gantry-sim eds")]
struct EdsArgs {
    /// TOML file that lists the chain.
    #[arg(long)]
    config: String,
    /// CANopen node id of the slave (its `node = N`).
    #[arg(long)]
    node: u8,
    /// Where to write the EDS.
    #[arg(long)]
    out: PathBuf,
}

/// Writes the EDS of `--node` to `--out`.
fn eds(args: &EdsArgs) -> Result<(), Box<dyn std::error::Error>> {
    let config = SimConfig::load(&args.config)?;
    let name = args
        .out
        .file_name()
        .map_or_else(|| "node.eds".into(), |n| n.to_string_lossy().into_owned());
    let eds = gantry_sim::canopen::eds::for_chain_node(&config, args.node, &name)
        .map_err(|e| format!("{}: {e}", args.config))?;
    std::fs::write(&args.out, gantry_drives::canopen::eds::write_eds(&eds))
        .map_err(|e| format!("{}: {e}", args.out.display()))?;
    println!(
        "gantry-sim: EDS of node {} written to {}",
        args.node,
        args.out.display()
    );
    Ok(())
}

fn main() -> ExitCode {
    // A subcommand of its own arguments: the network's are not needed for it.
    if std::env::args_os().nth(1).is_some_and(|a| a == "eds") {
        let args = EdsArgs::parse_from(std::env::args_os().skip(1));
        return match eds(&args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("gantry-sim eds: {e}");
                ExitCode::FAILURE
            }
        };
    }
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
    let interface = match (&args.interface, &args.can) {
        (_, Some(can)) => return run_can(args, &config, can),
        (Some(interface), None) => interface,
        (None, None) => return Err("give --interface IFACE (EtherCAT) or --can IFACE".into()),
    };
    let mut chain = config.chain()?;
    let socket = RawSocket::open(interface)?;
    socket.stamp_arrivals()?;
    if let Some(priority) = args.priority {
        set_fifo(priority)?;
    }
    catch_stop_signals()?;
    println!(
        "gantry-sim: {} slaves on {}, applications every {} µs",
        chain.slaves().len(),
        interface,
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
    let mut serve = || -> std::io::Result<()> {
        loop {
            if end.is_some_and(|end| Instant::now() >= end) || STOP.load(Ordering::SeqCst) {
                return Ok(());
            }
            let wait = clock.until_next_period(&chain);
            match socket.recv_stamped(&mut buf, Some(wait))? {
                Some((n, age)) => {
                    let frame = buf.get_mut(..n).unwrap_or_default();
                    // Served at its arrival: a frame that waited while this process was
                    // not scheduled still meets the SYNC0 edges it met on the wire.
                    clock.catch_up_to_arrival(&mut chain, age);
                    match chain.process(frame) {
                        Ok(()) => {
                            socket.send(frame)?;
                            served += 1;
                            let arrived = Instant::now().checked_sub(age);
                            gaps.frame(arrived.unwrap_or_else(Instant::now), &chain);
                        }
                        // A real network drops what it cannot parse; so do we, and count it.
                        Err(_) => dropped += 1,
                    }
                }
                // Idle: the chain goes on to now (timers, the watchdog); after a stall
                // the applications replay the periods they missed (up to a second).
                None => clock.catch_up(&mut chain),
            }
        }
    };
    let served_result = serve();
    // Whoever started us may have stopped reading: a summary nobody reads is no error.
    let _ = writeln!(
        std::io::stdout(),
        "gantry-sim: served {served} frames, dropped {dropped} malformed; {gaps}"
    );
    // The records are written however the loop ended: a test wants them most when the
    // network failed.
    if let Some(path) = &args.record {
        write_records(path, &chain.records())?;
        println!("gantry-sim: drive records written to {}", path.display());
    }
    served_result?;
    Ok(())
}

/// The chain's CANopen nodes on CAN interface `can` until SIGTERM/SIGINT or `--seconds`:
/// frames from the wire go to the nodes as they come (at their kernel receive time), the
/// nodes' timers run every `cycle_us`, and what the nodes send goes out at once.
fn run_can(args: &Args, config: &SimConfig, can: &str) -> Result<(), Box<dyn std::error::Error>> {
    let mut network = CanNetwork::from_config(config, &args.config)?;
    let socket = CanSocket::open(can)?;
    if let Some(priority) = args.priority {
        set_fifo(priority)?;
    }
    catch_stop_signals()?;
    let nodes: Vec<String> = network
        .nodes()
        .iter()
        .map(|n| n.node().get().to_string())
        .collect();
    println!(
        "gantry-sim: CANopen nodes {} on {can}, timers every {} µs",
        nodes.join(", "),
        config.cycle_us
    );
    let period = u64::from(config.cycle_us) * 1_000;
    let start = monotonic_ns();
    let end = args
        .seconds
        .map(|s| start.saturating_add((s.max(0.0) * 1e9) as u64));
    // The nodes' clock: ns since start, never going back (a frame's kernel stamp may be
    // older than the last tick).
    let mut now = 0u64;
    let mut next_tick = start;
    let mut lost = 0u64;
    let result = loop {
        let wall = monotonic_ns();
        if STOP.load(Ordering::SeqCst) || end.is_some_and(|end| wall >= end) {
            break Ok(());
        }
        let mut failure = None;
        let mut send = |frame: &CanFrame| match socket.send(frame) {
            Ok(()) => {}
            // A full transmit queue loses the frame, as a real controller's would.
            Err(CanSocketError::BufferFull { .. }) => lost += 1,
            Err(e) => {
                failure.get_or_insert(e);
            }
        };
        // The timers first, so a busy bus cannot starve them.
        if wall >= next_tick {
            now = now.max(wall - start);
            network.tick(now, &mut send);
            next_tick = if next_tick + period > wall {
                next_tick + period
            } else {
                wall + period
            };
        }
        match socket.recv_until(next_tick) {
            Ok(Some(received)) => {
                let at = received.stamp_ns.unwrap_or_else(monotonic_ns);
                now = now.max(at.saturating_sub(start));
                network.receive(&received.frame, now, &mut send);
            }
            Ok(None) => {}
            Err(e) => break Err(e),
        }
        if let Some(e) = failure {
            break Err(e);
        }
    };
    let counters = network.counters();
    let _ = writeln!(
        std::io::stdout(),
        "gantry-sim: received {} frames, sent {}, lost {lost} (transmit queue full), \
         skipped {} (29-bit or error frames)",
        counters.received,
        counters.sent,
        socket.skipped()
    );
    result?;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_records_file_has_one_entry_per_chain_position() {
        let config = SimConfig::parse(
            "cycle_us = 1000\n[[slave]]\nkind = \"servo\"\n[[slave]]\nkind = \"servo\"\n",
            "sim.toml",
        )
        .unwrap();
        let chain = config.chain().unwrap();
        let path =
            std::env::temp_dir().join(format!("gantry-sim-record-{}.json", std::process::id()));
        write_records(&path, &chain.records()).unwrap();
        let back = gantry_sim::plant::record::read_records(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(
            back,
            vec![Some(gantry_sim::plant::record::DriveRecord::default()); 2]
        );
    }

    #[test]
    fn sigterm_asks_the_loop_to_stop() {
        catch_stop_signals().unwrap();
        assert!(!STOP.load(Ordering::SeqCst));
        // SAFETY: raising a signal whose handler was just installed.
        assert_eq!(unsafe { libc::raise(libc::SIGTERM) }, 0);
        assert!(
            STOP.load(Ordering::SeqCst),
            "the process lives on and the flag is set"
        );
    }
}
