//! `gantry demo` (the default; `--bus ethercat`): the product as a newcomer first sees it.
//! Three CiA-402 servos simulated on the in-process EtherCAT network are brought up and
//! driven by what `gantry run` runs — the configuration file, the bus bring-up, the
//! [`Engine`](gantry::runtime::engine::Engine), requests through a [`Controller`], the
//! kernel — with the script's moves sent
//! as Controller commands: enable, x homed on its reference cam and index pulse (MoveHome,
//! judged by the simulated drive's own record), set position, PTP moves buffered and blended, a modulo
//! axis across its wrap both ways and turning several periods, a halt, a stop; at the end x
//! and y as an axis group tracing a rounded rectangle ([`super::group`], plotted as an XY
//! path beside the time plots).
//!
//! In [`lockstep`](super::lockstep): each frame passes the simulated chain in the demo's
//! thread and the network's time moves one cycle per cycle
//! ([`StepClock`](gantry::runtime::clock::StepClock)), so the run is deterministic, needs no
//! root and no real-time thread, and the drives — as strict as shipped (two SYNC0 periods
//! without a setpoint take one out of Op) — see a master exactly on time.
//!
//! It prints what a commissioning engineer looks at: the slaves found, their AL state and
//! process data, distributed clocks and where the frames land in the SYNC0 period, the
//! cycle figures at the end, and each axis' final state. The drives judge what reached
//! them ([`crate::drive_records`]): any drive fault, axis error, bus fault or broken
//! invariant fails the demo with what went wrong.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use gantry_kernel::axis::command::{
    BufferMode, Command, HaltMode, MoveDirection, MovePtp, MoveVelocity, PositioningMode,
    PowerCommand,
};
use gantry_kernel::homing::{HomingMode, MoveHome, MoveHomeCall, SwitchConfig};
use gantry_sim::chain::SlaveChain;
use gantry_sim::plant::record::{write_records, DriveRecord};
use gantry_sim::plant::servo::crossings::Crossed;
use gantry_sim::plant::servo::probe::{index_crossing, HOME_INPUT};
use gantry_sim::plant::servo::ServoDrive;

use super::group::GroupCheck;
use super::lockstep::{Advance, Lockstep};
use super::runner::{Limits, Runner, Watch};
use super::sync::{self, SyncCheck};
use super::{step, DemoArgs, DemoError, DemoReport, Step, Wait};
use crate::drive_records::{judge, AxisBound, Conditions, Verdict};
use crate::plot::{self, Panel};
use crate::simulator::{self, SimLink};
use gantry::config::Config;
use gantry::ethercat::bus::EthercatBus;
use gantry::ethercat::frame;
use gantry::runtime::bus::CycleBus;
use gantry::runtime::controller::Controller;
use gantry::runtime::engine::LateReply;
use gantry::runtime::protocol::TraceSample;
use gantry::trace::Trace;

/// The demo's configuration, written to its output folder as [`CONFIG_FILE`].
pub const CONFIG_TOML: &str = include_str!("gantry.toml");
/// The simulated chain it names, written beside it as [`SERVOS_FILE`].
pub const SERVOS_TOML: &str = include_str!("demo-servos.toml");
/// File name of the configuration in the output folder.
pub const CONFIG_FILE: &str = "gantry.toml";
/// File name of the simulated chain in the output folder (as `[bus] simulator` names it).
pub const SERVOS_FILE: &str = "demo-servos.toml";

/// Trace samples the engine's ring holds between two drains (the demo drains every
/// [`DRAIN_EVERY`] cycles).
const TRACE_RING: usize = 4096;
const DRAIN_EVERY: u64 = 100;
/// Cycles between two status frames (250 ms of the network's time).
const FRAME_CYCLES: u64 = 250;
/// Longest the slaves may take to report OP (the health monitor gives them 5 s).
const OP_LIMIT_CYCLES: u64 = 10_000;
/// Longest the script may run.
const SCRIPT_LIMIT_CYCLES: u64 = 60_000;
/// Cycles run after the last move, so the trace shows the axes at rest.
const TAIL_CYCLES: u64 = 300;

/// Brings the bus of `config` up — its `[bus] simulator` in this process, each frame
/// passing the chain in this thread — and builds the engine on it as `gantry run` does,
/// minus the real-time thread: the network's time then moves one cycle time per cycle,
/// in phase with SYNC0 as the engine holds it. One function, so that a change of the
/// bring-up's steps (who builds the kernel) is made here alone. With the simulated chain
/// (its drives' records).
fn start(
    config: &Config,
    out: &mut (dyn Write + Send),
) -> Result<(Lockstep<EthercatBus>, Arc<Mutex<SlaveChain>>), DemoError> {
    let sim = config.bus.simulator.as_deref().ok_or(DemoError::Network(
        "the demo's configuration has no in-process simulator",
    ))?;
    // The bus on the demo's own link: the library opens no simulator.
    let (link, simulated) = simulator::open(sim, SimLink::Lockstep)?;
    let bus = EthercatBus::bring_up_on(config, link, out)?;
    if !simulated.step_by_hand() {
        return Err(DemoError::Network("the simulated chain is not in lockstep"));
    }
    let chain = simulated.chain();
    let period_ns = u64::from(config.bus.cycle_us) * 1000;
    let start_ns = lock(&chain).now_ns();
    let stepped = chain.clone();
    let advance: Advance = Box::new(move |to_ns| lock(&stepped).run_until(to_ns, period_ns));
    let mut net = Lockstep::start(bus, config, TRACE_RING, start_ns, advance)?;
    // Every reply is in before the exchange looks for it: no wait ever runs out.
    net.engine.set_late_reply(LateReply::WAIT);
    Ok((net, chain))
}

/// The chain, even if a thread panicked holding it (the demo's thread is the only one
/// that steps it; its state is whole between two calls).
fn lock(chain: &Mutex<SlaveChain>) -> std::sync::MutexGuard<'_, SlaveChain> {
    chain.lock().unwrap_or_else(PoisonError::into_inner)
}

/// How the demo homes x (Jetter MoveHome): search negative for the reference cam
/// (`[slave.switches]` of its servo: 2 mm to 4 mm below where its encoder stands at
/// power-up), fast; then slowly back off the cam's positive end to the first index pulse
/// beyond it (the CiA 402 way, methods 1–14); x = 0 there. The limit switches (below
/// −20 mm, above 410 mm) would reverse the search.
pub const HOME_X: MoveHome = MoveHome {
    direction: MoveDirection::Negative,
    switch_config: SwitchConfig::RefAndLimitSwitch,
    mode: HomingMode::ZeroPulse2Phase,
    acceleration: 500.0,
    jerk: 20_000.0,
    speed_switch_search: 20.0,
    max_distance_switch_search: 50.0,
    speed_reference_search: 2.0,
    max_distance_reference_search: 10.0,
    reference_offset: 0.0,
    normal_position: 0.0,
};

/// The simulator's verdict on x's homing: x = 0 mm must be the index pulse the drive
/// crossed last before the reference was set — read from the drive's own record of what
/// its load crossed (not from the master) — within one count. `x` is its drive at the end
/// of the script, when x stands at 0 again.
pub(super) fn homing_verdict(x: &ServoDrive, out: &mut dyn Write) -> Result<(), DemoError> {
    let log = x.crossings();
    let index = log
        .since(0)
        .filter(|c| c.what == Crossed::Index)
        .map(|c| c.at)
        .min_by_key(|&at| (at - x.position_counts()).abs());
    let at = x.position_counts();
    // MoveHome's reference: the first index pulse beyond the cam's positive end.
    let p = &x.params;
    let expected = p.switches.cam(HOME_INPUT).and_then(|cam| {
        index_crossing(
            cam.to,
            i64::MAX / 4,
            i64::from(p.index_at),
            i64::from(p.counts_per_rev),
        )
        .map(|e| e.at)
    });
    match index {
        Some(i) if (at - i).abs() <= 1 && Some(i) == expected => {
            let _ = writeln!(
                out,
                ">> x homed: x = 0 mm stands at drive count {at}, the index pulse its drive \
                 crossed at {i} (the simulator's record)"
            );
            Ok(())
        }
        _ => Err(DemoError::Fault(format!(
            "x's homing: x = 0 mm stands at drive count {at}, not on the index pulse beyond \
             its reference cam ({expected:?}) that its drive crossed (nearest {index:?})"
        ))),
    }
}

/// The script, sent through the [`Controller`] as an application would: the moves of x, y
/// and c ([`motion_script`]) and, beside them, the synchronised axes' ([`super::sync`]);
/// at the end x and y as the axis group `xy` ([`super::group`]).
pub fn script() -> Vec<Step> {
    let mut steps = motion_script();
    super::sync::insert(&mut steps);
    super::group::insert(&mut steps);
    steps
}

/// The moves of x, y and c (the CANopen demo runs them too).
pub fn motion_script() -> Vec<Step> {
    use PositioningMode::*;
    let enable = Command::Power(PowerCommand::Enable);
    let set = |position| Command::SetPosition {
        position,
        relative: false,
    };
    let ptp = |mode, target| Command::MovePtp(MovePtp::new(mode, target));
    vec![
        step(
            Wait::Now,
            "x",
            enable,
            "x-on",
            "enable the drives (CiA-402: Shutdown, Switch on, Enable operation)",
        ),
        step(Wait::Now, "y", enable, "y-on", ""),
        step(Wait::Now, "c", enable, "c-on", ""),
        step(
            Wait::Done("x-on"),
            "x",
            Command::MoveHome(MoveHomeCall::all(HOME_X)),
            "x-home",
            "x: MoveHome on its reference switch and index pulse (negative: onto the cam at \
             20 mm/s, then slowly back off it to the next index pulse, latched by the drive's \
             touch probe); x = 0 mm there",
        ),
        step(
            Wait::Done("y-on"),
            "y",
            set(0.0),
            "y-home",
            "set reference: y = 0 mm, c = 300° (the drives' encoders stand elsewhere)",
        ),
        step(Wait::Done("c-on"), "c", set(300.0), "c-home", ""),
        step(
            Wait::Done("x-home"),
            "x",
            ptp(AbsNormal, 150.0),
            "x-ptp",
            "x: S-curve MovePtp 150 mm",
        ),
        step(
            Wait::Done("y-home"),
            "y",
            ptp(AbsNormal, 60.0),
            "y-1",
            "y: trapezoid MovePtp 60, Buffered +40, BlendingNext 200 (no stop between them)",
        ),
        step(
            Wait::Now,
            "y",
            Command::MovePtp(MovePtp::new(RelTarget, 40.0).buffered(BufferMode::Buffered)),
            "y-2",
            "",
        ),
        step(
            Wait::Now,
            "y",
            Command::MovePtp(
                MovePtp::new(AbsNormal, 200.0)
                    .speed(80.0)
                    .buffered(BufferMode::BlendingNext),
            ),
            "y-3",
            "",
        ),
        step(
            Wait::Done("c-home"),
            "c",
            ptp(AbsModuloPos, 60.0),
            "c-1",
            "c: AbsModuloPos 60 from 300: forward across 360° = 0°",
        ),
        step(
            Wait::Done("c-1"),
            "c",
            ptp(AbsModuloAuto, 300.0),
            "c-2",
            "c: AbsModuloAuto 300: the short way, back across the wrap",
        ),
        step(
            Wait::Done("x-ptp"),
            "x",
            ptp(RelActual, -50.0),
            "x-rel",
            "x: MovePtp RelActual -50",
        ),
        step(
            Wait::Done("c-2"),
            "c",
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 540.0)),
            "c-vel",
            "c: MoveVelocity +540°/s: turns on across the wrap",
        ),
        step(
            Wait::Done("x-rel"),
            "x",
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 120.0)),
            "x-vel",
            "x: MoveVelocity +120 mm/s",
        ),
        step(
            Wait::Seconds(0.5),
            "x",
            Command::Halt {
                mode: HaltMode::Normal,
                deceleration: Some(600.0),
            },
            "x-halt",
            "x: Halt",
        ),
        step(
            Wait::Seconds(0.6),
            "c",
            Command::Stop {
                deceleration: Some(3600.0),
            },
            "c-stop",
            "c: Stop",
        ),
        step(Wait::Done("c-stop"), "c", Command::Release, "c-release", ""),
        step(
            Wait::Done("x-halt"),
            "x",
            ptp(AbsNormal, 0.0),
            "x-zero",
            "all axes home: x, y to 0 mm, c to 0° the short way",
        ),
        step(Wait::Done("y-3"), "y", ptp(AbsNormal, 0.0), "y-zero", ""),
        step(
            Wait::Done("c-release"),
            "c",
            ptp(AbsModuloAuto, 0.0),
            "c-zero",
            "",
        ),
    ]
}

/// Writes the demo's configuration and the simulated chain `servos` to `dir` and loads
/// the configuration from there, as `gantry run --config` would; with a capture to `pcap`.
pub(super) fn write_config(
    dir: &Path,
    servos: &str,
    pcap: Option<&Path>,
) -> Result<Config, DemoError> {
    write_files_and_load(
        dir,
        &[
            (CONFIG_FILE, CONFIG_TOML),
            (SERVOS_FILE, servos),
            (sync::CAM_FILE, sync::CAM_TOML),
        ],
        pcap,
    )
}

/// Writes a demo's configuration and the files beside it — its simulated chain, a cam
/// table — (`files`: the configuration first) to `dir` and loads the configuration from
/// there, as `gantry run --config` would; with a capture to `pcap`.
pub(super) fn write_files_and_load(
    dir: &Path,
    files: &[(&str, &str)],
    pcap: Option<&Path>,
) -> Result<Config, DemoError> {
    std::fs::create_dir_all(dir).map_err(io_error(dir))?;
    for &(name, text) in files {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(io_error(&path))?;
    }
    let first = files.first().map_or("", |f| f.0);
    let mut config = Config::load(&dir.join(first).display().to_string())?;
    if let Some(path) = pcap {
        // Said here with the file's name, before anything else is done.
        std::fs::File::create(path).map_err(io_error(path))?;
        config.bus.pcap = Some(path.display().to_string());
    }
    Ok(config)
}

pub(super) fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> DemoError + '_ {
    move |source| DemoError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Runs the demo.
pub fn run(args: &DemoArgs, out: &mut (dyn Write + Send)) -> Result<DemoReport, DemoError> {
    run_on(args, SERVOS_TOML, out)
}

/// Runs the demo on the simulated chain `servos` (a gantry-sim TOML, a servo per axis in
/// the demo's order) instead of its own: drives that cannot follow, or fewer drives than
/// axes, show how it fails. Once per process (the EtherCAT bus starts once per process).
pub fn run_on(
    args: &DemoArgs,
    servos: &str,
    out: &mut (dyn Write + Send),
) -> Result<DemoReport, DemoError> {
    let config = write_config(&args.out, servos, args.pcap.as_deref())?;
    let _ = writeln!(
        out,
        ">> gantry demo: {} CiA-402 servos simulated on an in-process EtherCAT network, \
         driven by gantry's engine in lockstep (configuration: {})",
        config
            .axes
            .iter()
            .filter(|a| a.axis_type == gantry::config::AxisType::Real)
            .count(),
        args.out.join(CONFIG_FILE).display()
    );
    let _ = writeln!(out, ">> EtherCAT bring-up");
    let (mut net, chain) = start(&config, out)?;
    // The ram's cam table: the configuration's `[[cam]]`, read from the file written
    // beside it and put into its kernel slot at start, as `gantry run` does.
    let cam = sync::configured_cam(&config)?;
    let _ = writeln!(
        out,
        ">> cam table {:?} from {} ({} points, {}, periodic: {}) in the kernel's slot {}",
        cam.name,
        cam.file,
        cam.table.points().len(),
        cam.table.interpolation(),
        cam.table.is_periodic(),
        cam.slot
    );
    let check = SyncCheck::of_config(&config, cam.table.clone())?;
    let mut runner = Runner::new(&config, args.speed, FRAME_CYCLES, true);
    let mut run = Run::new(&config, "EtherCAT")
        .with_sync(check)
        .with_group(GroupCheck::of_config(&config)?);
    let result = run
        .wait_for_op(&mut runner, &mut net, &chain, out)
        .and_then(|()| {
            let limits = Limits {
                cycles: net.cycles() + SCRIPT_LIMIT_CYCLES,
                tail: TAIL_CYCLES,
            };
            runner.script(&mut net, &mut run, script(), limits, out)
        });
    let result = result.and_then(
        |()| match lock(&chain).slaves().first().map(|s| s.device()) {
            Some(gantry_sim::plant::DeviceModel::Servo(x)) => homing_verdict(x, out),
            _ => Err(DemoError::Fault("x's drive is not a servo".into())),
        },
    );
    // Whatever happened, the drives are disabled, the bus goes down to PreOp (the capture
    // is flushed) and the drives' records are kept for whoever looks into it.
    let ended = runner.shut_down(
        &mut net,
        &mut run,
        "drives disabled; the bus goes to PreOp",
        out,
    );
    let counters = net.engine.counters();
    let figures = net.ctl.figures();
    let lost = net.engine.bus.health().lost_total;
    let wkc = net.engine.bus.health().wkc_total;
    let stats = net.engine.bus.frame_stats();
    let wire = net.engine.bus.cyclic_wire_bytes();
    net.engine.into_bus().shut_down(out);
    let records = lock(&chain).records();
    write_records(&args.out.join("drive-records.json"), &records)?;
    // The cycle figures, also when the demo failed: they may say why.
    let _ = writeln!(
        out,
        ">> cycles: {} ({} with every slave's AL state read: at start and after a wrong \
         working counter); lost frames {lost}; working-counter errors {wkc}; overruns {}",
        counters.cycles, stats.state_reads, counters.overruns
    );
    let _ = writeln!(
        out,
        ">> on the wire: {wire} B per cycle ({:.1} µs at 100 Mbit/s); the master's work per \
         cycle p50 {:.1} µs, p99 {:.1} µs (host time)",
        frame::wire_us(wire),
        figures.compute.p50_us,
        figures.compute.p99_us
    );
    result?;
    ended?;
    if lost != 0 || wkc != 0 {
        return Err(DemoError::Fault(format!(
            "{lost} frames lost and {wkc} working-counter errors on a lockstep network"
        )));
    }
    let verdict = judge_records(&records, &config)?;
    run.wraps_said(&verdict, &records, &config, out);
    if let Some(check) = &run.sync {
        check.said(f64::from(config.bus.cycle_us) * 1e-6, out)?;
    }
    if let Some(check) = &run.group {
        check.said(out)?;
    }
    let (csv, svg) = run.write_files(&args.out, &config)?;
    let xy = run.write_xy(&args.out)?;
    Ok(DemoReport {
        csv,
        svg,
        xy,
        simulated_s: counters.cycles as f64 * f64::from(config.bus.cycle_us) * 1e-6,
        cycles: counters.cycles,
        cycle_s: f64::from(config.bus.cycle_us) * 1e-6,
    })
}

/// The drive invariant (issue 10 §6) on what each simulated drive recorded: no target
/// step beyond the axis' `vmax · T` plus one count, no following-error fault, and — the
/// demo runs lockstep, one frame per SYNC0 period — no missed or doubled setpoint; and no
/// drive fault of any kind.
pub(super) fn judge_records(
    records: &[Option<DriveRecord>],
    config: &Config,
) -> Result<Verdict, DemoError> {
    let bounds = AxisBound::of_config(config).map_err(DemoError::Invariant)?;
    let verdict = judge(
        records,
        &bounds,
        Conditions {
            injects_following_error: false,
            phase_locked: true,
        },
    );
    check_verdict(&verdict, records, &bounds)?;
    Ok(verdict)
}

/// Fails on a broken invariant, then on any drive that faulted.
fn check_verdict(
    verdict: &Verdict,
    records: &[Option<DriveRecord>],
    bounds: &[AxisBound],
) -> Result<(), DemoError> {
    if !verdict.holds() {
        return Err(DemoError::Invariant(verdict.broken.join("; ")));
    }
    let faulted: Vec<String> = bounds
        .iter()
        .filter_map(|b| {
            let r = records.get(b.drive)?.as_ref()?;
            (r.faults > 0).then(|| {
                format!(
                    "axis {} (drive {}): {} fault(s), the last 0x{:04X}",
                    b.axis, b.drive, r.faults, r.last_fault_code
                )
            })
        })
        .collect();
    if faulted.is_empty() {
        Ok(())
    } else {
        Err(DemoError::Fault(format!(
            "a drive faulted: {}",
            faulted.join("; ")
        )))
    }
}

/// What the demos on a bus record while they run: the engine's trace, the modulo axes'
/// wraps, where the frames land in the SYNC0 period (EtherCAT with DC).
pub(super) struct Run {
    names: Vec<String>,
    /// Per axis, its modulo period.
    periods: Vec<Option<f64>>,
    samples: Vec<TraceSample>,
    /// Per modulo axis: wraps of the set position forward and backward.
    wraps: Vec<(u32, u32)>,
    /// Where in the SYNC0 period the frames reached the reference clock (ns), since OP.
    dc_offsets: Option<(u64, u64)>,
    in_op: bool,
    cycle_us: u32,
    /// The bus, as the plot's title names it.
    bus: &'static str,
    /// The synchronised axes' check (the EtherCAT demo's).
    sync: Option<SyncCheck>,
    /// The axis group's check (the EtherCAT demo's).
    group: Option<GroupCheck>,
}

impl<B: CycleBus> Watch<B> for Run {
    /// The trace, and where the frames land in the SYNC0 period.
    fn cycled(&mut self, net: &Lockstep<B>) -> Result<(), DemoError> {
        let n = net.cycles();
        if let (true, Some(offset)) = (self.in_op, net.engine.bus.dc_offset_ns()) {
            let (lo, hi) = self.dc_offsets.get_or_insert((offset, offset));
            (*lo, *hi) = ((*lo).min(offset), (*hi).max(offset));
        }
        if n % DRAIN_EVERY == 0 {
            self.drain(&net.ctl);
        }
        if let Some(check) = self.sync.as_mut() {
            check.observe(&net.engine.cycle.kernel, net.time())?;
        }
        if let Some(check) = self.group.as_mut() {
            check.observe(&net.engine.cycle.kernel, net.time())?;
        }
        Ok(())
    }

    fn settled(&mut self, net: &Lockstep<B>) {
        self.drain(&net.ctl);
    }

    fn shutdown_cycled(&mut self, net: &Lockstep<B>, ended: bool) -> Result<(), DemoError> {
        if ended {
            self.drain(&net.ctl);
        }
        Ok(())
    }
}

impl Run {
    /// For the axes of `config` on the bus named `bus` (in the plot's title).
    pub(super) fn new(config: &Config, bus: &'static str) -> Self {
        Self {
            bus,
            names: config.axes.iter().map(|a| a.name.clone()).collect(),
            periods: config.axes.iter().map(|a| a.modulo).collect(),
            samples: Vec::new(),
            wraps: vec![(0, 0); config.axes.len()],
            dc_offsets: None,
            in_op: false,
            cycle_us: config.bus.cycle_us,
            sync: None,
            group: None,
        }
    }

    /// With the synchronised axes checked every cycle and plotted apart.
    pub(super) fn with_sync(self, check: SyncCheck) -> Self {
        Self {
            sync: Some(check),
            ..self
        }
    }

    /// With the axis group checked every cycle and its path plotted.
    pub(super) fn with_group(self, check: GroupCheck) -> Self {
        Self {
            group: Some(check),
            ..self
        }
    }

    /// Trace samples since the last drain; counts the modulo axes' wraps.
    fn drain(&mut self, ctl: &Controller) {
        let from = self.samples.len();
        ctl.drain_trace(&mut self.samples);
        for k in from.max(1)..self.samples.len() {
            let (a, b) = (&self.samples[k - 1], &self.samples[k]);
            for (i, period) in self.periods.iter().enumerate() {
                let (Some(p), Some(w)) = (period, self.wraps.get_mut(i)) else {
                    continue;
                };
                // Moving across it: not an axis at rest on 0 whose set follows its
                // actual to just below it.
                match (wrap_crossed(a, b, i, *p), b.set_velocity[i]) {
                    (1, v) if v > 0.0 => w.0 += 1,
                    (-1, v) if v < 0.0 => w.1 += 1,
                    _ => {}
                }
            }
        }
    }

    /// Waits for every slave to report OP, then shows the bus.
    fn wait_for_op(
        &mut self,
        runner: &mut Runner,
        net: &mut Lockstep<EthercatBus>,
        chain: &Mutex<SlaveChain>,
        out: &mut (dyn Write + Send),
    ) -> Result<(), DemoError> {
        // The engine asks the slaves for OP once its frames are held in phase with SYNC0;
        // the health monitor says when every slave has reported OP.
        let mut waited = 0;
        while net.engine.bus.health().is_starting() || net.engine.bus.health().any_fault() {
            if waited >= OP_LIMIT_CYCLES || !net.engine.bus.health().is_starting() {
                runner.check(&net.ctl.snapshot())?;
                return Err(DemoError::Fault(format!(
                    "the slaves did not report OP in {waited} cycles"
                )));
            }
            runner.cycle(net, self, out)?;
            waited += 1;
        }
        self.in_op = true;
        self.say_bus(net, chain, waited, out);
        Ok(())
    }

    /// The bus as the master sees it once every slave is in OP.
    fn say_bus(
        &self,
        net: &Lockstep<EthercatBus>,
        chain: &Mutex<SlaveChain>,
        cycles: u64,
        out: &mut (dyn Write + Send),
    ) {
        let bus = &net.engine.bus;
        let image = bus.image();
        let expected_wkc = net.engine.bus.health().expected_working_counter();
        // The demo's chain: the bring-up found as many slaves (it said so above).
        let slaves = lock(chain).slaves().len();
        let _ = writeln!(
            out,
            ">> every slave reported OP {cycles} cycles after the bring-up (the cycle asks \
             each for OP once its frames are held in phase with SYNC0)"
        );
        let _ = writeln!(out, "   slave  AL state  inputs  outputs  axis");
        // The image is cloned for its per-slave output sizes (it hands out outputs only
        // mutably): a few hundred bytes, once.
        let mut outputs = image.clone();
        for position in 0..slaves {
            let axis = (0..self.names.len())
                .find(|&a| net.engine.cycle.drive_of(a) == position)
                .and_then(|a| self.names.get(a))
                .map_or("-", String::as_str);
            // In OP: the health monitor read every slave's AL state as OP before it let
            // the start end, and has seen none leave since.
            let state = match net.engine.bus.health().fault(position) {
                None => "OP".to_string(),
                Some(f) => f.to_string(),
            };
            let _ = writeln!(
                out,
                "   {position:<5}  {state:<8}  {:>4} B  {:>5} B  {axis}",
                image.inputs(position).len(),
                outputs.outputs_mut(position).len()
            );
        }
        let wire = bus.cyclic_wire_bytes();
        let _ = writeln!(
            out,
            ">> process data: {} B in {} LRW datagram(s), expected working counter {expected_wkc}; \
             {wire} B on the wire per cycle ({:.1} µs at 100 Mbit/s)",
            image.len(),
            image.chunks().len(),
            frame::wire_us(wire)
        );
        let dc = bus.dc();
        let snap = net.ctl.snapshot();
        match (dc.active, snap.dc_offset_ns, snap.dc_target_ns) {
            (true, Some(offset), Some(target)) => {
                let _ = writeln!(
                    out,
                    ">> distributed clocks: SYNC0 every {} µs; the frames reach the reference \
                     clock {:.1} µs into the SYNC0 period (the cycle holds them at {:.1} µs)",
                    self.cycle_us,
                    offset as f64 / 1e3,
                    target as f64 / 1e3
                );
            }
            _ => {
                let _ = writeln!(out, ">> distributed clocks: off (free run)");
            }
        }
    }

    /// The axes are in operation from now on (the trace counts their wraps; on EtherCAT
    /// the frames' place in the SYNC0 period is watched).
    pub(super) fn in_operation(&mut self) {
        self.in_op = true;
    }

    /// After the run: the modulo axes' wraps and what their drives' targets did meanwhile.
    pub(super) fn wraps_said(
        &self,
        verdict: &Verdict,
        records: &[Option<DriveRecord>],
        config: &Config,
        out: &mut (dyn Write + Send),
    ) {
        if let Some((lo, hi)) = self.dc_offsets {
            let _ = writeln!(
                out,
                ">> distributed clocks: in OP the frames reached the reference clock between \
                 {:.1} and {:.1} µs into the SYNC0 period",
                lo as f64 / 1e3,
                hi as f64 / 1e3
            );
        }
        for (i, a) in config.axes.iter().enumerate() {
            let (Some(period), Some((fwd, back))) = (a.modulo, self.wraps.get(i)) else {
                continue;
            };
            let bound = AxisBound::of_config(config)
                .ok()
                .and_then(|b| b.into_iter().find(|b| b.axis == a.name));
            let step = records
                .get(a.drive)
                .and_then(Option::as_ref)
                .map(|r| r.max_target_step_counts);
            if let (Some(bound), Some(step)) = (bound, step) {
                let _ = writeln!(
                    out,
                    ">> {}: crossed its wrap ({period} → 0) {fwd} times forward and {back} \
                     backward; its drive's target moved at most {step} counts in a cycle \
                     (vmax · T: {} counts) — no step at the wrap",
                    a.name, bound.max_step_counts
                );
            }
        }
        let _ = writeln!(
            out,
            ">> the drives' verdict (drive-records.json): no fault, no missed or doubled \
             setpoint; {}",
            verdict.summary.join("; ")
        );
    }

    /// The trace (CSV) and the plot (SVG).
    pub(super) fn write_files(
        &self,
        dir: &Path,
        config: &Config,
    ) -> Result<(PathBuf, PathBuf), DemoError> {
        let mut channels = Vec::new();
        for n in &self.names {
            channels.extend([format!("{n}.set"), format!("{n}.actual"), format!("{n}.v")]);
        }
        // Modulo axes once more, unwrapped, so that the plot shows their travel.
        let modulo: Vec<(usize, f64)> = self
            .periods
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.map(|p| (i, p)))
            .collect();
        for &(i, _) in &modulo {
            let n = &self.names[i];
            channels.extend([
                format!("{n}.set_unwrapped"),
                format!("{n}.actual_unwrapped"),
            ]);
        }
        let width = channels.len();
        let mut trace = Trace::new(channels, self.samples.len().max(1));
        // Whole periods crossed so far by each modulo axis' set and actual position.
        let mut turns = vec![(0.0f64, 0.0f64); modulo.len()];
        let mut row = Vec::with_capacity(width);
        for (k, s) in self.samples.iter().enumerate() {
            row.clear();
            for i in 0..self.names.len() {
                row.extend([s.set[i], s.actual[i], s.set_velocity[i]]);
            }
            for (m, &(i, p)) in modulo.iter().enumerate() {
                if let Some(prev) = k.checked_sub(1).and_then(|k| self.samples.get(k)) {
                    turns[m].0 += f64::from(crossing(prev.set[i], s.set[i], p)) * p;
                    turns[m].1 += f64::from(crossing(prev.actual[i], s.actual[i], p)) * p;
                }
                row.extend([s.set[i] + turns[m].0, s.actual[i] + turns[m].1]);
            }
            trace.push(s.time_s, &row)?;
        }
        let csv = dir.join("trace.csv");
        let svg = dir.join("plot.svg");
        trace.write_csv(&csv)?;
        // The synchronised axes get panels of their own.
        let (master, gears, cams) = self
            .sync
            .as_ref()
            .map_or((usize::MAX, Vec::new(), Vec::new()), SyncCheck::axes);
        let synced = |i: usize| i == master || gears.contains(&i) || cams.contains(&i);
        // Channels of axis i: set and actual; unwrapped if it is modulo.
        let position = |i: usize| -> [usize; 2] {
            match modulo.iter().position(|&(a, _)| a == i) {
                Some(m) => [
                    self.names.len() * 3 + 2 * m,
                    self.names.len() * 3 + 2 * m + 1,
                ],
                None => [i * 3, i * 3 + 1],
            }
        };
        let linear: Vec<usize> = (0..self.names.len())
            .filter(|&i| self.periods[i].is_none() && !synced(i))
            .flat_map(position)
            .collect();
        let rotary: Vec<usize> = modulo
            .iter()
            .filter(|&&(i, _)| !synced(i))
            .flat_map(|&(i, _)| position(i))
            .collect();
        let units = |i: usize| config.axes.get(i).map_or("", |a| a.units.as_str());
        let mut panels = vec![
            Panel {
                title: format!("set and actual position ({}) over {}", units(0), self.bus),
                channels: linear,
            },
            Panel {
                title: "modulo axes, unwrapped: set and actual position".into(),
                channels: rotary,
            },
        ];
        if self.sync.is_some() {
            // The virtual master's actual is its set: drawn once.
            let master_set = position(master)[0];
            panels.push(Panel {
                title: "gearing, unwrapped (°): virtual master m; g1 1:1, g2 -1:2 set and actual"
                    .into(),
                channels: std::iter::once(master_set)
                    .chain(gears.iter().flat_map(|&i| position(i)))
                    .collect(),
            });
            panels.push(Panel {
                title: format!(
                    "camming: ram set and actual (mm) on {}; m (°, within its turn)",
                    sync::CAM_FILE
                ),
                channels: cams
                    .iter()
                    .flat_map(|&i| position(i))
                    .chain([master * 3])
                    .collect(),
            });
        }
        panels.push(Panel {
            title: "set velocity (units/s)".into(),
            channels: (0..self.names.len()).map(|i| i * 3 + 2).collect(),
        });
        let doc = plot::svg(&trace, &panels);
        std::fs::write(&svg, doc).map_err(io_error(&svg))?;
        Ok((csv, svg))
    }
}

impl Run {
    /// The axis group's path while it moved, set and actual, as an XY plot in `dir`
    /// (`xy.svg`, beside the time plots), where the demo checked a group.
    pub(super) fn write_xy(&self, dir: &Path) -> Result<Option<PathBuf>, DemoError> {
        let Some((group, (from, to))) = self.group.as_ref().and_then(|g| Some((g, g.span()?)))
        else {
            return Ok(None);
        };
        let [a, b] = group.axes();
        let name = |i: usize| self.names.get(i).map_or("?", String::as_str);
        let channels = vec![
            format!("{}.set", name(a)),
            format!("{}.set", name(b)),
            format!("{}.actual", name(a)),
            format!("{}.actual", name(b)),
        ];
        let mut trace = Trace::new(channels, self.samples.len().max(1));
        for s in self
            .samples
            .iter()
            .filter(|s| (from..=to).contains(&s.time_s))
        {
            let (Some(&xs), Some(&ys), Some(&xa), Some(&ya)) =
                (s.set.get(a), s.set.get(b), s.actual.get(a), s.actual.get(b))
            else {
                continue;
            };
            trace.push(s.time_s, &[xs, ys, xa, ya])?;
        }
        let svg = dir.join(XY_FILE);
        let doc = plot::xy_svg(
            &trace,
            &format!(
                "group {}: a rounded rectangle, set and actual path (mm)",
                super::group::GROUP
            ),
            &[(0, 1), (2, 3)],
        );
        std::fs::write(&svg, doc).map_err(io_error(&svg))?;
        Ok(Some(svg))
    }
}

/// File name of the axis group's XY plot in the output folder.
pub const XY_FILE: &str = "xy.svg";

/// Whether axis `i`'s set position, wrapped into `[0, period)`, went across the wrap
/// between two consecutive samples (see [`crossing`]).
fn wrap_crossed(a: &TraceSample, b: &TraceSample, i: usize, period: f64) -> i32 {
    crossing(a.set[i], b.set[i], period)
}

/// Whether a position wrapped into `[0, period)` went across the wrap from `before` to
/// `after`, one cycle later: +1 forward (from near `period` to near 0), -1 backward, 0
/// not. Between two cycles an axis moves far less than a quarter period: a larger jump is
/// a new reference (SetPosition), not a crossing.
fn crossing(before: f64, after: f64, period: f64) -> i32 {
    let (jump, moved) = (after - before, short_way(after, before, period));
    if jump.abs() <= period / 2.0 || moved.abs() > period / 4.0 {
        0
    } else if moved > 0.0 {
        1
    } else {
        -1
    }
}

/// `x - reference` wrapped into `[-period/2, period/2)`: how far apart two positions of a
/// modulo axis are, the short way (the actual follows the set within far less than half
/// a period).
fn short_way(x: f64, reference: f64, period: f64) -> f64 {
    (x - reference + period / 2.0).rem_euclid(period) - period / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The demo's configuration as the demo loads it: written with the files beside it
    /// (its cam table) to a folder of this test's own.
    fn config() -> Config {
        static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!(
            "gantry-demo-unit-config-{}-{n}",
            std::process::id()
        ));
        let config = write_config(&dir, SERVOS_TOML, None).expect("the demo's configuration");
        let _ = std::fs::remove_dir_all(&dir);
        config
    }

    #[test]
    fn the_demo_fails_with_the_axis_and_the_rule_when_a_drive_saw_a_step_or_faulted() {
        let config = config();
        let bounds = AxisBound::of_config(&config).unwrap();
        // x: 250 mm/s at 2^17 counts per 5 mm: 6553.6 counts per ms, bound 6554.
        assert_eq!(bounds[0].max_step_counts, 6554);
        let mut ok = DriveRecord::default();
        ok.target(0);
        ok.target(6554);
        let mut step = ok;
        step.target(6554 + 6555);
        // c: 720°/s through 10:1 on 2^17 counts per motor revolution: bound 2622.
        assert_eq!(bounds[2].max_step_counts, 2622);
        let mut c = DriveRecord::default();
        c.target(0);
        c.target(-2622);
        // g1, g2 (720°/s direct: bound 263) and ram (500 mm/s on 5 mm: bound 13108); the
        // virtual master m has no drive, so no bound.
        assert_eq!(
            bounds[3..]
                .iter()
                .map(|b| (b.axis.as_str(), b.drive, b.max_step_counts))
                .collect::<Vec<_>>(),
            [("g1", 3, 263), ("g2", 4, 263), ("ram", 5, 13108)]
        );
        let mut f = DriveRecord::default();
        f.target(0);
        f.target(263);
        let followers = [Some(f); 3];
        let records = [[Some(ok), Some(ok), Some(c)], followers].concat();
        let verdict = judge(
            &records,
            &bounds,
            Conditions {
                injects_following_error: false,
                phase_locked: true,
            },
        );
        check_verdict(&verdict, &records, &bounds).unwrap();
        assert!(
            verdict.summary[0]
                .starts_with("x: largest target step 6554 counts (bound 6554), 2 targets"),
            "{verdict:?}"
        );
        let records = [[Some(ok), Some(step), Some(c)], followers].concat();
        let verdict = judge(
            &records,
            &bounds,
            Conditions {
                injects_following_error: false,
                phase_locked: true,
            },
        );
        let e = check_verdict(&verdict, &records, &bounds).unwrap_err();
        assert!(
            e.to_string().starts_with(
                "drive invariant broken: axis y (drive 1): target stepped 6555 counts in one \
                 cycle at target #2; vmax · T + 1 count is 6554; DriveRecord {"
            ),
            "{e}"
        );
        // A fault of any kind fails the demo, with its code.
        let mut faulted = c;
        faulted.fault(0xFF01);
        let records = [[Some(ok), Some(ok), Some(faulted)], followers].concat();
        let verdict = judge(
            &records,
            &bounds,
            Conditions {
                injects_following_error: false,
                phase_locked: true,
            },
        );
        let e = check_verdict(&verdict, &records, &bounds).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the demo stopped: a drive faulted: axis c (drive 2): 1 fault(s), the last 0xFF01"
        );
        // A drive missing from the chain.
        let records = [Some(ok), Some(ok)];
        let verdict = judge(&records, &bounds, Conditions::default());
        let e = check_verdict(&verdict, &records, &bounds).unwrap_err();
        assert!(
            e.to_string()
                .contains("axis c (drive 2): no drive record at that chain position"),
            "{e}"
        );
    }

    #[test]
    fn the_demos_chain_file_is_a_valid_simulator_configuration_with_a_servo_per_real_axis() {
        let dir = std::env::temp_dir().join(format!("gantry-demo-config-{}", std::process::id()));
        let config = write_config(&dir, SERVOS_TOML, None).unwrap();
        let sim =
            gantry_sim::config::SimConfig::load(config.bus.simulator.as_deref().unwrap()).unwrap();
        // A servo per real axis (the virtual master m has none), at its `drive` position.
        let real: Vec<usize> = config
            .axes
            .iter()
            .filter(|a| a.axis_type == gantry::config::AxisType::Real)
            .map(|a| a.drive)
            .collect();
        assert_eq!(real, [0, 1, 2, 3, 4, 5]);
        assert_eq!(sim.chain().unwrap().slaves().len(), real.len());
        assert!(dir.join(sync::CAM_FILE).exists());
        assert_eq!(sim.cycle_us, config.bus.cycle_us);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_wrap_is_crossed_only_moving_across_it() {
        let sample = |set: f64, v: f64| {
            let mut s = TraceSample {
                time_s: 0.0,
                set: [0.0; gantry::runtime::protocol::TRACE_AXES],
                set_velocity: [0.0; gantry::runtime::protocol::TRACE_AXES],
                actual: [0.0; gantry::runtime::protocol::TRACE_AXES],
            };
            (s.set[1], s.set_velocity[1]) = (set, v);
            s
        };
        let cross = |a: (f64, f64), b: (f64, f64)| {
            wrap_crossed(&sample(a.0, a.1), &sample(b.0, b.1), 1, 360.0)
        };
        assert_eq!(cross((359.5, 300.0), (0.2, 300.0)), 1);
        assert_eq!(cross((0.2, -300.0), (359.5, -300.0)), -1);
        assert_eq!(cross((10.0, 300.0), (12.0, 300.0)), 0);
        // SetPosition 300 on an axis at rest at 85°: a new reference, no crossing.
        assert_eq!(cross((85.0, 0.0), (300.0, 0.0)), 0);
        // An axis at rest on 0 whose set follows its actual to just below it does cross
        // (the trace unwraps it), but not moving: the demo does not count it.
        assert_eq!(cross((0.0, 0.0), (359.9999, 0.0)), -1);
        assert!((short_way(359.9, 0.1, 360.0) + 0.2).abs() < 1e-9);
        assert!((short_way(0.1, 359.9, 360.0) - 0.2).abs() < 1e-9);
    }
}
