//! `gantry demo --bus none`: the motion kernel without bus hardware. Three simulated axes
//! (actual = set, as SPEC §1 defines) go through a scripted sequence of PTP moves in
//! several modes, buffered and blended moves, a velocity move with reverse, jogs with
//! merge and a halt at the actual position; a status table shows it live; the trace (CSV)
//! and a plot (SVG) are written to a folder it prints. No root, no network, no
//! configuration file.
//!
//! It runs what `gantry run` runs — a [`Config`],
//! [`Cycle::from_config`](gantry::runtime::cycle::Cycle::from_config), the
//! [`Engine`](gantry::runtime::engine::Engine), the script's commands through a
//! [`Controller`](gantry::runtime::controller::Controller) ([`runner`]) — on the simulated
//! axes' bus ([`SimulatedBus`]: CiA-402 drives with no hardware whose position is the
//! target sent), in [`lockstep`] with nothing to step: the drives answer within the
//! exchange.
//!
//! `gantry demo` itself, the newcomer's first look, runs the product over simulated drives
//! on the in-process EtherCAT network ([`ethercat`]); `gantry demo --bus canopen` over
//! simulated CANopen nodes on the in-memory CAN bus ([`canopen`]).

use std::io::Write;
use std::path::{Path, PathBuf};

use gantry_kernel::axis::command::{
    BufferMode, Command, HaltMode, Jog, JogProfile, MergeSpeed, MoveDirection, MovePtp,
    MoveVelocity, PositioningMode, PowerCommand,
};
use gantry_kernel::group::run::GroupCmd;
use thiserror::Error;

pub mod canopen;
pub mod ethercat;
pub mod group;
pub mod limits;
pub mod lockstep;
pub mod runner;
pub mod sync;

use crate::plot::{self, Panel};
use gantry::config::{
    AxisSection, BusSection, Config, DefaultsSection, FaultsSection, MaxSection, RtSection,
    ScalingSection,
};
use gantry::simulated::SimulatedBus;
use gantry::trace::{Trace, TraceError};
use lockstep::Lockstep;
use runner::{Limits, Runner, Watch, SNAPSHOT_CYCLES};

/// Options of `gantry demo`.
#[derive(Clone, Debug)]
pub struct DemoArgs {
    /// Folder for trace.csv and plot.svg.
    pub out: PathBuf,
    /// Simulated seconds per wall-clock second (0: as fast as possible).
    pub speed: f64,
    /// Cycle time (s) of the bus-less demo (the EtherCAT demo's is its configuration's,
    /// `bus.cycle_us`).
    pub cycle_s: f64,
    /// Write every EtherCAT frame here (the EtherCAT demo).
    pub pcap: Option<PathBuf>,
}

impl Default for DemoArgs {
    fn default() -> Self {
        Self {
            out: PathBuf::from("out/demo"),
            speed: 4.0,
            cycle_s: 0.001,
            pcap: None,
        }
    }
}

/// What the demo produced.
#[derive(Clone, Debug)]
pub struct DemoReport {
    /// The CSV trace.
    pub csv: PathBuf,
    /// The SVG plot.
    pub svg: PathBuf,
    /// The XY plot of the axis group's path (set and actual), where the demo has a group.
    pub xy: Option<PathBuf>,
    /// Simulated time (s).
    pub simulated_s: f64,
    /// Cycles run.
    pub cycles: u64,
    /// Their cycle time (s).
    pub cycle_s: f64,
}

/// Why the demo failed.
#[derive(Debug, Error)]
pub enum DemoError {
    /// An axis of the bus-less demo's configuration was refused (a bug in the demo).
    #[error("demo axis {axis:?}: {key}: {reason}")]
    Axis {
        /// The axis.
        axis: String,
        /// The configuration key.
        key: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The bus-less demo's cycle time is not one the engine runs.
    #[error("cycle time {0} s: the demo runs whole µs from 250 to 4000")]
    CycleTime(f64),
    /// The simulated axes' bus could not be made for the demo's configuration.
    #[error(transparent)]
    Simulated(#[from] gantry::simulated::SimulatedError),
    /// A step of the script was refused or failed.
    #[error("demo step {label} ({axis}: {command}) failed")]
    Step {
        /// The step.
        label: &'static str,
        /// Axis name.
        axis: &'static str,
        /// Command name.
        command: &'static str,
        /// The error (boxed: the kernel's error is large, this one travels far).
        #[source]
        error: Box<gantry_kernel::axis::command::CommandError>,
    },
    /// The script waited for a step that never finished.
    #[error("demo step {0} did not finish within the time limit")]
    Timeout(&'static str),
    /// The script names an unknown axis or label (a bug in the demo).
    #[error("demo script names unknown {0}")]
    Script(&'static str),
    /// Writing the output failed.
    #[error(transparent)]
    Trace(#[from] TraceError),
    /// The demo's configuration file was refused (a bug in the demo).
    #[error(transparent)]
    Configuration(#[from] gantry::config::ConfigError),
    /// The EtherCAT network did not come up.
    #[error(transparent)]
    Start(#[from] gantry::ethercat::bus::StartError),
    /// The CANopen bus did not come up.
    #[error(transparent)]
    CanStart(#[from] gantry::canopen::bring_up::StartError),
    /// The cycle does not fit the configuration or its bus.
    #[error(transparent)]
    Cycle(#[from] gantry::runtime::cycle::SetupError),
    /// The demo's in-process network cannot run.
    #[error("EtherCAT: {0}")]
    Network(&'static str),
    /// An axis, a drive or the bus failed while the demo ran: what and why.
    #[error("the demo stopped: {0}")]
    Fault(String),
    /// The drives' records could not be written.
    #[error(transparent)]
    Records(#[from] gantry_sim::plant::record::RecordsFileError),
    /// A simulated drive saw the master break the drive invariant (issue 10 §6): a target
    /// step beyond `vmax · T`, a following-error fault, a missed or doubled setpoint.
    #[error("drive invariant broken: {0}")]
    Invariant(String),
    /// The demo's configuration lacks its cam table (a bug in the demo).
    #[error("the demo's configuration has no [[cam]] {name:?} in slot {slot}")]
    NoCam {
        /// The table's name.
        name: &'static str,
        /// Its slot.
        slot: usize,
    },
    /// Creating the output folder or writing the plot failed.
    #[error("cannot write {path}")]
    Io {
        /// The path.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}
/// When a script step is issued.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Wait {
    /// Straight after the previous step.
    Now,
    /// This many seconds after the previous step.
    Seconds(f64),
    /// When the command of step `label` is done.
    Done(&'static str),
    /// When the commands of all these steps are done.
    DoneAll(&'static [&'static str]),
    /// This many seconds after the command of step `label` is seen done (a group's axes
    /// take a move again once they are back in Standstill, the cycle after).
    DoneFor(&'static str, f64),
}

/// What a step commands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Order {
    /// A command to the axis the step names.
    Axis(Command),
    /// A command to the axis group the step names (`[[group]]`).
    Group(GroupCmd),
}

impl Order {
    /// The command's (function block's) name.
    pub const fn name(&self) -> &'static str {
        match self {
            Order::Axis(c) => c.name(),
            Order::Group(g) => g.name(),
        }
    }
}

/// One step of the script.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// What to wait for before issuing it.
    pub wait: Wait,
    /// Axis name (a group's name for a group command).
    pub axis: &'static str,
    /// The command.
    pub command: Order,
    /// Name of the step (for `Wait::Done` and the log).
    pub label: &'static str,
    /// What the step shows, printed when it is issued.
    pub says: &'static str,
}

/// A step of a script: `command` on `axis` once `wait` is over, named `label`, saying
/// `says` (nothing if empty) when issued.
pub const fn step(
    wait: Wait,
    axis: &'static str,
    command: Command,
    label: &'static str,
    says: &'static str,
) -> Step {
    Step {
        wait,
        axis,
        command: Order::Axis(command),
        label,
        says,
    }
}

/// A step of a script that commands axis group `group`.
pub const fn group_step(
    wait: Wait,
    group: &'static str,
    command: GroupCmd,
    label: &'static str,
    says: &'static str,
) -> Step {
    Step {
        wait,
        axis: group,
        command: Order::Group(command),
        label,
        says,
    }
}

/// Cycle time of the bus-less demo (µs) for `cycle_s` seconds, if it is a cycle the
/// engine runs (a whole number of µs, 250 to 4000, as `bus.cycle_us`).
fn cycle_us(cycle_s: f64) -> Result<u32, DemoError> {
    let us = (cycle_s * 1e6).round();
    if (cycle_s * 1e6 - us).abs() > 1e-6 || !(250.0..=4000.0).contains(&us) {
        return Err(DemoError::CycleTime(cycle_s));
    }
    Ok(us as u32)
}

/// One of the demo's axes on the simulated drive at position `drive`: the full CSP
/// mapping, a 17-bit encoder, `units_per_load_rev` after `gear`:1, the given maxima and
/// default dynamics (speed, acceleration = deceleration, jerk, ramp).
fn axis(
    name: &str,
    drive: usize,
    gear: u32,
    units_per_load_rev: f64,
    max: [f64; 3],
    defaults: [f64; 3],
    ramp: &str,
) -> AxisSection {
    let [speed, acceleration, jerk] = defaults;
    AxisSection {
        name: name.into(),
        axis_type: gantry::config::AxisType::Real,
        source: None,
        encoder_input: None,
        drive,
        node: None,
        eds: None,
        kind: "linear".into(),
        units: "mm".into(),
        modulo: None,
        direction: "both".into(),
        software_limits: Some([-10.0, 400.0]),
        scaling: ScalingSection {
            counts_per_motor_rev: 1 << 17,
            motor_revs: gear,
            load_revs: 1,
            units_per_load_rev,
            invert: false,
        },
        max: MaxSection {
            speed: max[0],
            acceleration: max[1],
            deceleration: None,
            jerk: max[2],
        },
        defaults: DefaultsSection {
            speed: Some(speed),
            acceleration: Some(acceleration),
            deceleration: Some(acceleration),
            jerk: Some(jerk),
            ramp: Some(ramp.into()),
            target_window: None,
        },
        quick_stop_deceleration: None,
        homing_required: Some(true),
        target_monitoring: Default::default(),
        pdo: "csp".into(),
        switches: Default::default(),
        encoder: Default::default(),
        homed_at_start: false,
        sync_limit: Default::default(),
        drive_homing: None,
        commutation: Default::default(),
    }
}

/// The demo's configuration: three simulated axes (SPEC §1: actual = set), each on a
/// drive of the simulated axes' bus — `x` linear S-curve and `y` linear trapezoid on 5 mm
/// ball screws, `c` a rotary table modulo 360° through a 10:1 gear with Sine ramps —
/// cycling every `cycle_us` µs.
pub fn config(cycle_us: u32) -> Result<Config, DemoError> {
    let x = axis(
        "x",
        0,
        1,
        5.0,
        [200.0, 2000.0, 20_000.0],
        [100.0, 500.0, 5_000.0],
        "scurve",
    );
    let y = axis(
        "y",
        1,
        1,
        5.0,
        [200.0, 2000.0, 20_000.0],
        [80.0, 300.0, 5_000.0],
        "trapezoid",
    );
    let mut c = axis(
        "c",
        2,
        10,
        360.0,
        [720.0, 3600.0, 36_000.0],
        [360.0, 1440.0, 14_400.0],
        "sine",
    );
    (c.kind, c.units, c.modulo, c.software_limits) =
        ("rotary".into(), "deg".into(), Some(360.0), None);
    let axes = vec![x, y, c];
    let kernel_axes = axes
        .iter()
        .map(|a| {
            a.kernel_config().map_err(|(key, reason)| DemoError::Axis {
                axis: a.name.clone(),
                key,
                reason,
            })
        })
        .collect::<Result<_, _>>()?;
    Ok(Config {
        path: "gantry demo --bus none".into(),
        bus: BusSection {
            kind: "none".into(),
            interface: None,
            simulator: None,
            cycle_us,
            simulator_record: None,
            pcap: None,
            dc: false,
            faults: FaultsSection::default(),
            bitrate: None,
            heartbeat_ms: None,
            heartbeat_timeout_ms: None,
            master_node: None,
            master_timeout_ms: None,
            sync_counter: None,
            sdo_max_bytes: None,
        },
        rt: RtSection::default(),
        // The demo saves nothing.
        service: Default::default(),
        eds: vec![None; axes.len()],
        axes,
        kernel_axes,
        cams: Vec::new(),
        groups: Vec::new(),
        group_defaults: Vec::new(),
    })
}

const fn ptp(mode: PositioningMode, target: f64) -> Command {
    Command::MovePtp(MovePtp::new(mode, target))
}

/// The scripted sequence.
pub fn script() -> Vec<Step> {
    use PositioningMode::*;
    let mut jog = Jog::new(MoveDirection::Negative, 60.0, 400.0, 400.0);
    jog.profile = JogProfile::SCurve;
    jog.merge = true;
    jog.merge_speed = MergeSpeed::Current;
    let mut jog_programmed = jog;
    jog_programmed.merge_speed = MergeSpeed::Programmed;
    jog_programmed.speed = 20.0;
    vec![
        step(
            Wait::Now,
            "x",
            Command::Power(PowerCommand::Enable),
            "x-on",
            "enable all axes",
        ),
        step(
            Wait::Now,
            "y",
            Command::Power(PowerCommand::Enable),
            "y-on",
            "",
        ),
        step(
            Wait::Now,
            "c",
            Command::Power(PowerCommand::Enable),
            "c-on",
            "",
        ),
        step(
            Wait::Done("x-on"),
            "x",
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
            "x-home",
            "set reference (homed)",
        ),
        step(
            Wait::Done("y-on"),
            "y",
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
            "y-home",
            "",
        ),
        step(
            Wait::Done("c-on"),
            "c",
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
            "c-home",
            "",
        ),
        // x: S-curve PTP, then a relative move from the actual position.
        step(
            Wait::Now,
            "x",
            ptp(AbsNormal, 150.0),
            "x-ptp",
            "x: S-curve MovePtp AbsNormal 150",
        ),
        // y: three buffered/blended moves: no standstill between them.
        step(
            Wait::Now,
            "y",
            ptp(AbsNormal, 60.0),
            "y-1",
            "y: trapezoid MovePtp 60, then Buffered +40, then BlendingNext 200",
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
                    .speed(40.0)
                    .buffered(BufferMode::BlendingNext),
            ),
            "y-3",
            "",
        ),
        // c: modulo modes.
        step(
            Wait::Now,
            "c",
            ptp(AbsModuloPos, 90.0),
            "c-1",
            "c: Sine ramps, AbsModuloPos 90, AbsModuloAuto 300 (goes -150), KeepDirection 200",
        ),
        step(Wait::Done("c-1"), "c", ptp(AbsModuloAuto, 300.0), "c-2", ""),
        step(
            Wait::Done("c-2"),
            "c",
            ptp(AbsModuloKeepDirection, 200.0),
            "c-3",
            "",
        ),
        step(
            Wait::Done("x-ptp"),
            "x",
            ptp(RelActual, -50.0),
            "x-rel",
            "x: MovePtp RelActual -50",
        ),
        // x: velocity move, reverse, halt at the actual position.
        step(
            Wait::Done("x-rel"),
            "x",
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Positive, 120.0)),
            "x-vel",
            "x: MoveVelocity +120",
        ),
        step(
            Wait::Seconds(1.0),
            "x",
            Command::Reverse,
            "x-rev",
            "x: Reverse",
        ),
        step(
            Wait::Seconds(1.2),
            "x",
            Command::Halt {
                mode: HaltMode::AtActualPosition,
                deceleration: Some(300.0),
            },
            "x-halt",
            "x: Halt AtActualPosition (brakes, comes back)",
        ),
        // y: a jog merging into the running move at its current speed, then at 20 units/s.
        step(
            Wait::Done("y-3"),
            "y",
            ptp(AbsNormal, 20.0),
            "y-back",
            "y: MovePtp back to 20",
        ),
        step(
            Wait::Seconds(0.8),
            "y",
            Command::Jog(jog),
            "y-jog",
            "y: Jog Merge (current speed)",
        ),
        step(
            Wait::Seconds(0.5),
            "y",
            Command::Jog(jog_programmed),
            "y-jog2",
            "y: Jog Merge (programmed 20)",
        ),
        step(
            Wait::Seconds(1.0),
            "y",
            Command::Halt {
                mode: HaltMode::Normal,
                deceleration: None,
            },
            "y-halt",
            "y: Halt",
        ),
        // c: velocity with a new speed, then stop and release.
        step(
            Wait::Done("c-3"),
            "c",
            Command::MoveVelocity(MoveVelocity::new(MoveDirection::Negative, 180.0)),
            "c-vel",
            "c: MoveVelocity -180°/s",
        ),
        step(
            Wait::Seconds(1.0),
            "c",
            Command::Change(gantry_kernel::axis::command::DynamicsChange::Speed, 540.0),
            "c-fast",
            "c: NewSpeed 540°/s",
        ),
        step(
            Wait::Seconds(1.0),
            "c",
            Command::Stop {
                deceleration: Some(1800.0),
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
            "all axes home",
        ),
        step(Wait::Done("y-halt"), "y", ptp(AbsNormal, 0.0), "y-zero", ""),
        step(Wait::Now, "c", ptp(AbsModuloAuto, 0.0), "c-zero", ""),
    ]
}

/// Longest the script may run (simulated seconds) before the demo gives up.
const TIME_LIMIT_S: f64 = 60.0;

/// Simulated seconds between two status frames.
const FRAME_S: f64 = 0.25;

/// Simulated seconds run after the last move, so the trace shows the axes at rest.
const TAIL_S: f64 = 0.3;

/// Runs the demo.
pub fn run(args: &DemoArgs, out: &mut impl Write) -> Result<DemoReport, DemoError> {
    let cycle_us = cycle_us(args.cycle_s)?;
    let config = config(cycle_us)?;
    // Lockstep with nothing to step: the drives answer within the exchange. The demo
    // traces from the kernel itself (set acceleration, whole periods): the engine's trace
    // ring is not read.
    let bus = SimulatedBus::of_config(&config)?;
    let mut net = Lockstep::start(bus, &config, 1, 0, Box::new(|_| {}))?;
    let _ = writeln!(
        out,
        ">> gantry demo --bus none: {} simulated axes (actual = set: drives with no \
         hardware, CiA-402 answering at once), driven by gantry's engine in lockstep",
        config.axes.len()
    );
    // A frame on a snapshot: a multiple of the snapshot's cycles.
    let frame_cycles = ((FRAME_S / args.cycle_s).round() as u64)
        .div_ceil(SNAPSHOT_CYCLES)
        .max(1)
        * SNAPSHOT_CYCLES;
    let mut runner = Runner::new(&config, args.speed, frame_cycles, false);
    let mut run = Run::new(&config, args);
    let limits = Limits {
        cycles: (TIME_LIMIT_S / net.cycle_time()) as u64,
        tail: (TAIL_S / net.cycle_time()).round() as u64,
    };
    let result = runner.script(&mut net, &mut run, script(), limits, out);
    let ended = runner.shut_down(&mut net, &mut run, "drives disabled", out);
    result?;
    ended?;
    let (csv, svg) = run.write_files(&args.out)?;
    Ok(DemoReport {
        csv,
        svg,
        xy: None,
        simulated_s: net.time(),
        cycles: net.cycles(),
        cycle_s: f64::from(cycle_us) * 1e-6,
    })
}

/// What the bus-less demo records: the kernel's set values every cycle.
struct Run {
    names: Vec<String>,
    /// Per axis, its modulo period.
    periods: Vec<Option<f64>>,
    trace: Trace,
    sample: Vec<f64>,
}

impl Watch<SimulatedBus> for Run {
    fn cycled(&mut self, net: &Lockstep<SimulatedBus>) -> Result<(), DemoError> {
        self.record(net)
    }

    fn settled(&mut self, _net: &Lockstep<SimulatedBus>) {}

    fn shutdown_cycled(
        &mut self,
        net: &Lockstep<SimulatedBus>,
        _ended: bool,
    ) -> Result<(), DemoError> {
        self.record(net)
    }
}

impl Run {
    fn new(config: &Config, args: &DemoArgs) -> Self {
        let names: Vec<String> = config.axes.iter().map(|a| a.name.clone()).collect();
        let channels = names
            .iter()
            .flat_map(|n| ["p", "v", "a"].map(|q| format!("{n}.{q}")))
            .collect();
        Self {
            periods: config.axes.iter().map(|a| a.modulo).collect(),
            trace: Trace::new(channels, (TIME_LIMIT_S / args.cycle_s) as usize / 4),
            sample: vec![0.0; names.len() * 3],
            names,
        }
    }

    /// This cycle's set values into the trace: modulo axes unwrapped (their whole
    /// periods added), so that the plot shows the travel.
    fn record(&mut self, net: &Lockstep<SimulatedBus>) -> Result<(), DemoError> {
        let kernel = &net.engine.cycle.kernel;
        for (i, period) in self.periods.iter().enumerate() {
            let status = kernel.axis_status(i).copied().unwrap_or_default();
            let turns = period.map_or(0.0, |p| status.turns as f64 * p);
            if let Some(dst) = self.sample.get_mut(i * 3..i * 3 + 3) {
                dst.copy_from_slice(&[status.set.p + turns, status.set.v, status.set.a]);
            }
        }
        self.trace.push(kernel.time(), &self.sample)?;
        Ok(())
    }

    /// The trace (CSV) and the plot (SVG) in `dir`.
    fn write_files(&self, dir: &Path) -> Result<(PathBuf, PathBuf), DemoError> {
        std::fs::create_dir_all(dir).map_err(|source| DemoError::Io {
            path: dir.display().to_string(),
            source,
        })?;
        let csv = dir.join("trace.csv");
        let svg = dir.join("plot.svg");
        self.trace.write_csv(&csv)?;
        let panel = |title: &str, q: usize| Panel {
            title: title.into(),
            channels: (0..self.names.len()).map(|i| i * 3 + q).collect(),
        };
        let doc = plot::svg(
            &self.trace,
            &[
                panel("set position (units; c in °, unwrapped)", 0),
                panel("set velocity (units/s)", 1),
                panel("set acceleration (units/s²)", 2),
            ],
        );
        std::fs::write(&svg, doc).map_err(|source| DemoError::Io {
            path: svg.display().to_string(),
            source,
        })?;
        Ok((csv, svg))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_demos_configuration_is_its_three_axes_and_a_bad_cycle_is_refused() {
        let config = config(1000).unwrap();
        let names: Vec<&str> = config.axes.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, ["x", "y", "c"]);
        let ramps: Vec<_> = config.kernel_axes.iter().map(|k| k.defaults.ramp).collect();
        use gantry_kernel::profile::RampType;
        assert_eq!(
            ramps,
            [RampType::SCurve, RampType::Trapezoid, RampType::Sine]
        );
        let c = &config.kernel_axes[2];
        assert_eq!(c.mechanics.modulo.map(|m| m.period()), Some(360.0));
        let bus = SimulatedBus::of_config(&config).unwrap();
        gantry::runtime::cycle::Cycle::from_config(&config, &bus).unwrap();
        assert_eq!(cycle_us(0.001).unwrap(), 1000);
        for bad in [0.0001, 0.005, 0.0010004, f64::NAN] {
            let e = cycle_us(bad).unwrap_err();
            assert_eq!(
                e.to_string(),
                format!("cycle time {bad} s: the demo runs whole µs from 250 to 4000")
            );
        }
    }

    #[test]
    fn demo_runs_to_the_end_and_writes_its_files() {
        let dir = std::env::temp_dir().join(format!("gantry-demo-{}", std::process::id()));
        let args = DemoArgs {
            out: dir.clone(),
            speed: 0.0,
            cycle_s: 0.001,
            pcap: None,
        };
        let mut log = Vec::new();
        let report = run(&args, &mut log).unwrap();
        let text = String::from_utf8(log).unwrap();
        assert!(text.contains("Halt AtActualPosition"));
        assert!(report.simulated_s > 5.0 && report.simulated_s < TIME_LIMIT_S);
        // Every axis home, its drive where it was sent, then switched off by the engine.
        for axis in ["x", "y", "c"] {
            let line = format!(
                "   {axis}: Standstill, set 0.0000, actual 0.0000, drive Operation enabled"
            );
            assert!(text.contains(&line), "{line:?} in\n{text}");
        }
        assert!(text.ends_with(">> drives disabled\n"), "{text}");
        let csv = std::fs::read_to_string(&report.csv).unwrap();
        assert_eq!(csv.lines().count() as u64, report.cycles + 1);
        let svg = std::fs::read_to_string(&report.svg).unwrap();
        assert_eq!(svg.matches("<polyline").count(), 9);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
