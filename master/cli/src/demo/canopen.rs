//! `gantry demo --bus canopen`: the EtherCAT demo's script on four CiA-402 servos
//! simulated as CANopen nodes, on the in-memory CAN bus at 1 Mbit/s with arbitration and
//! each frame's bit time ([`crate::can_simulator`], in lockstep). What `gantry run` runs
//! with `[bus] kind = "canopen"` brings them up and drives them — the configuration file,
//! the CANopen bring-up (NMT reset, boot-ups, device type and identity by SDO, the PDOs
//! mapped by SDO in pre-operational, NMT start), the
//! [`Engine`](gantry::runtime::engine::Engine) sending RPDOs then SYNC each cycle and
//! reading the TPDOs, requests through the
//! [`Controller`](gantry::runtime::controller::Controller), the kernel — through the same
//! [`runner`](super::runner) as the EtherCAT demo.
//!
//! The cycle is 2 ms: four drives' CSP PDOs (x's with its switches and touch probe) and the
//! SYNC take about 1.76 ms of the bus at 1 Mbit/s, which the configuration's bus-load check
//! accepts for 2 ms and refuses for 1 ms. x homes on its reference cam and index pulse
//! before it moves, as in the EtherCAT demo. The drives judge what reached them ([`crate::drive_records`]): any drive
//! fault, axis error, bus fault, lost TPDO or broken invariant fails the demo.

use std::io::Write;

use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};

use super::ethercat::{self, judge_records, write_files_and_load, Run};
use super::lockstep::{Advance, Lockstep};
use super::runner::{Limits, Runner};
use super::{step, DemoArgs, DemoError, DemoReport, Step, Wait};
use crate::can_simulator::{self, lock, SharedBus};
use gantry::canopen::CanopenBus;
use gantry::config::Config;
use gantry::runtime::bus::CycleBus;
use gantry_sim::plant::record::write_records;

/// The demo's configuration, written to its output folder as [`CONFIG_FILE`].
pub const CONFIG_TOML: &str = include_str!("gantry-canopen.toml");
/// The simulated nodes it names, written beside it as [`SERVOS_FILE`].
pub const SERVOS_TOML: &str = include_str!("demo-can-servos.toml");
/// File name of the configuration in the output folder.
pub const CONFIG_FILE: &str = "gantry.toml";
/// File name of the simulated nodes in the output folder (as `[bus] simulator` names it).
pub const SERVOS_FILE: &str = "demo-can-servos.toml";

/// x's node (it homes on its switch cam and index pulse).
const X_NODE: u8 = 1;

/// Trace samples the engine's ring holds between two drains (the trace is drained every
/// 100 cycles).
const TRACE_RING: usize = 4096;
/// Cycles between two status frames (250 ms at 2 ms).
const FRAME_CYCLES: u64 = 130;
/// Longest the script may run (60 s at 2 ms).
const SCRIPT_LIMIT_CYCLES: u64 = 30_000;
/// Cycles run after the last move, so the trace shows the axes at rest.
const TAIL_CYCLES: u64 = 150;

/// Brings the nodes of `config`'s `[bus] simulator` up on the in-memory bus (lockstep),
/// and builds the engine on them as `gantry run` does, minus the real-time thread: the
/// bus' time then moves one cycle per cycle. With the simulated bus (the drives' records).
fn start(
    config: &Config,
    out: &mut (dyn Write + Send),
) -> Result<(Lockstep<CanopenBus>, SharedBus), DemoError> {
    let (link, sim) = can_simulator::open(config, false)?.ok_or(DemoError::Network(
        "the demo's configuration has no in-process simulator",
    ))?;
    let bus = CanopenBus::bring_up_on(config, Box::new(link), out)?;
    let period_ns = u64::from(config.bus.cycle_us) * 1000;
    let start_ns = {
        let mut s = lock(&sim);
        s.stepped(period_ns);
        s.now_ns()
    };
    let stepped = sim.clone();
    let advance: Advance = Box::new(move |to_ns| lock(&stepped).cycle_at(to_ns));
    let net = Lockstep::start(bus, config, TRACE_RING, start_ns, advance)?;
    Ok((net, sim))
}

/// The EtherCAT demo's script, with a fourth axis, z, enabled, homed and moved down and
/// back beside the others.
pub fn script() -> Vec<Step> {
    let mut steps = ethercat::motion_script();
    let at = |steps: &[Step], label: &str| {
        steps
            .iter()
            .position(|s| s.label == label)
            .map_or(steps.len(), |i| i + 1)
    };
    let i = at(&steps, "c-on");
    steps.insert(
        i,
        step(
            Wait::Now,
            "z",
            Command::Power(PowerCommand::Enable),
            "z-on",
            "",
        ),
    );
    let i = at(&steps, "c-home");
    steps.insert(
        i,
        step(
            Wait::Done("z-on"),
            "z",
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
            "z-home",
            "",
        ),
    );
    let i = at(&steps, "y-3");
    steps.insert(
        i,
        step(
            Wait::Done("z-home"),
            "z",
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 50.0)),
            "z-down",
            "z: S-curve MovePtp 50 mm (its drive counts the other way: invert)",
        ),
    );
    let i = at(&steps, "y-zero");
    steps.insert(
        i,
        step(
            Wait::Done("z-down"),
            "z",
            Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, 0.0)),
            "z-zero",
            "",
        ),
    );
    steps
}

/// Runs the demo.
pub fn run(args: &DemoArgs, out: &mut (dyn Write + Send)) -> Result<DemoReport, DemoError> {
    let config = write_files_and_load(
        &args.out,
        &[(CONFIG_FILE, CONFIG_TOML), (SERVOS_FILE, SERVOS_TOML)],
        None,
    )?;
    let _ = writeln!(
        out,
        ">> gantry demo --bus canopen: {} CiA-402 servos simulated as CANopen nodes on an \
         in-memory CAN bus at {} kbit/s, driven by gantry's engine in lockstep \
         (configuration: {})",
        config.axes.len(),
        config.bus.bitrate.unwrap_or(0) / 1000,
        args.out.join(CONFIG_FILE).display()
    );
    let _ = writeln!(out, ">> CANopen bring-up");
    let (mut net, sim) = start(&config, out)?;
    say_bus(&net, &config, out);
    let mut runner = Runner::new(&config, args.speed, FRAME_CYCLES, true);
    let mut run = Run::new(&config, "CANopen");
    run.in_operation();
    let limits = Limits {
        cycles: net.cycles() + SCRIPT_LIMIT_CYCLES,
        tail: TAIL_CYCLES,
    };
    let result = runner
        .script(&mut net, &mut run, script(), limits, out)
        .and_then(|()| {
            let s = lock(&sim);
            match s.node(X_NODE).servo() {
                Some(x) => ethercat::homing_verdict(x, out),
                None => Err(DemoError::Fault("x's node is not a servo".into())),
            }
        });
    // Whatever happened, the drives are disabled and the nodes go to pre-operational;
    // the drives' records are kept for whoever looks into it.
    let ended = runner.shut_down(
        &mut net,
        &mut run,
        "drives disabled; the nodes go to pre-operational",
        out,
    );
    let counters = net.engine.counters();
    let figures = net.ctl.figures();
    let bus_counters = net.engine.bus.counters();
    let malformed = net.engine.bus.malformed();
    // The cycle has ended: the bus' time runs on with the shutdown's waits.
    lock(&sim).free_running();
    let _ = net.engine.into_bus().shut_down(out);
    let (records, frames, bus_ns) = {
        let s = lock(&sim);
        (s.records(&config), s.bus.log().len(), s.now_ns())
    };
    write_records(&args.out.join("drive-records.json"), &records)?;
    let cycle_ns = u64::from(config.bus.cycle_us) * 1000;
    let _ = writeln!(
        out,
        ">> cycles: {}; TPDO sets lost {} (incomplete {}); malformed frames {malformed}; \
         overruns {}",
        counters.cycles, bus_counters.lost, bus_counters.incomplete, counters.overruns
    );
    let _ = writeln!(
        out,
        ">> on the bus: {frames} frames in {:.2} s of bus time, {:.1} per cycle; the master's \
         work per cycle p50 {:.1} µs, p99 {:.1} µs (host time)",
        bus_ns as f64 * 1e-9,
        frames as f64 / (bus_ns / cycle_ns).max(1) as f64,
        figures.compute.p50_us,
        figures.compute.p99_us
    );
    result?;
    ended?;
    if bus_counters.lost != 0 || malformed != 0 {
        return Err(DemoError::Fault(format!(
            "{} TPDO sets lost and {malformed} malformed frames on a lockstep bus",
            bus_counters.lost
        )));
    }
    let verdict = judge_records(&records, &config)?;
    run.wraps_said(&verdict, &records, &config, out);
    let (csv, svg) = run.write_files(&args.out, &config)?;
    Ok(DemoReport {
        csv,
        svg,
        xy: None,
        simulated_s: counters.cycles as f64 * f64::from(config.bus.cycle_us) * 1e-6,
        cycles: counters.cycles,
        cycle_s: f64::from(config.bus.cycle_us) * 1e-6,
    })
}

/// The bus as the master brought it up: each node, what it is, its PDOs.
fn say_bus(net: &Lockstep<CanopenBus>, config: &Config, out: &mut (dyn Write + Send)) {
    let bus = &net.engine.bus;
    let _ = writeln!(
        out,
        "   node  device type  vendor      product     RPDOs  TPDOs  outputs  inputs  axis"
    );
    for (i, info) in bus.node_infos().iter().enumerate() {
        let hex = |v: Option<u32>| v.map_or("-".to_string(), |v| format!("0x{v:08X}"));
        let (rpdos, tpdos) = bus
            .plan(i)
            .map_or((0, 0), |p| (p.rpdos.len(), p.tpdos.len()));
        let _ = writeln!(
            out,
            "   {:<4}  0x{:08X}   {:<10}  {:<10}  {rpdos:>5}  {tpdos:>5}  {:>5} B  {:>4} B  {}",
            info.node.get(),
            info.device_type,
            hex(info.identity[0]),
            hex(info.identity[1]),
            bus.outputs(i).len(),
            bus.inputs(i).len(),
            config.axes.get(i).map_or("-", |a| a.name.as_str())
        );
    }
    let load = gantry::canopen::load::BusLoad::of_config(config);
    if let Ok(load) = load {
        let _ = writeln!(
            out,
            ">> every node Operational; each cycle: RPDOs, SYNC, TPDOs — {} bits of {} µs at \
             {} kbit/s ({:.0} % of the cycle's reply window)",
            load.bits,
            config.bus.cycle_us,
            load.bitrate / 1000,
            load.bits as f64 * 1e9
                / load.bitrate as f64
                / gantry::runtime::clock::reply_window_ns(load.period_ns) as f64
                * 100.0
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_demos_configuration_fits_its_bus_at_2_ms_and_not_at_1_ms() {
        let config = Config::parse(CONFIG_TOML, CONFIG_FILE).expect("the demo's configuration");
        assert_eq!(config.axes.len(), 4);
        assert_eq!(config.bus.cycle_us, 2000);
        let at_1_ms = CONFIG_TOML.replace("cycle_us = 2000", "cycle_us = 1000");
        let e = Config::parse(&at_1_ms, CONFIG_FILE)
            .unwrap_err()
            .to_string();
        assert!(e.contains("bus.bitrate"), "{e}");
        let sim = gantry_sim::config::SimConfig::parse(SERVOS_TOML, SERVOS_FILE)
            .expect("the demo's nodes");
        let nodes: Vec<Option<u8>> = sim.slaves.iter().map(|s| s.node()).collect();
        let axes: Vec<Option<u8>> = config.axes.iter().map(|a| a.node).collect();
        assert_eq!(nodes, axes);
        // The script names each axis, z included.
        let script = script();
        for axis in ["x", "y", "z", "c"] {
            assert!(script.iter().any(|s| s.axis == axis), "{axis}");
        }
    }
}
