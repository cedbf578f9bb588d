//! `gantry demo --bus none`: the motion kernel alone. Three simulated axes (actual = set, as
//! SPEC §1 defines) go through a scripted sequence of PTP moves in several modes, buffered
//! and blended moves, a velocity move with reverse, jogs with merge and a halt at the
//! actual position; a status table shows it live; the trace (CSV) and a plot (SVG) are
//! written to a folder it prints. No root, no network, no configuration file.
//!
//! `gantry demo` itself, the newcomer's first look, runs the product over simulated drives
//! on the in-process EtherCAT network ([`ethercat`]).

use std::collections::HashMap;
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use gantry_kernel::axis::command::{
    BufferMode, Command, HaltMode, Jog, JogProfile, MergeSpeed, MoveDirection, MovePtp,
    MoveVelocity, PositioningMode, PowerCommand,
};
use gantry_kernel::axis::handle::{CommandStatus, HandleId};
use gantry_kernel::mechanics::{Modulo, MotionKind};
use gantry_kernel::profile::{Limits, RampType};
use gantry_kernel::{AxisConfig, AxisKind, Kernel};
use thiserror::Error;

pub mod ethercat;

use crate::plot::{self, Panel};
use crate::status_table::{self, Live, Row};
use crate::trace::{Trace, TraceError};

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
    /// The kernel refused the demo's axes (a bug in the demo).
    #[error("demo configuration rejected")]
    Config(#[from] gantry_kernel::axis::ConfigError),
    /// A step of the script was refused or failed.
    #[error("demo step {label} ({axis}: {command}) failed")]
    Step {
        /// The step.
        label: &'static str,
        /// Axis name.
        axis: &'static str,
        /// Command name.
        command: &'static str,
        /// The error.
        #[source]
        error: gantry_kernel::axis::command::CommandError,
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
    Configuration(#[from] crate::config::ConfigError),
    /// The EtherCAT network did not come up.
    #[error(transparent)]
    Start(#[from] crate::ethercat::bus::StartError),
    /// The cycle does not fit the configuration or its bus.
    #[error(transparent)]
    Cycle(#[from] crate::runtime::cycle::SetupError),
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
}

/// One step of the script.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// What to wait for before issuing it.
    pub wait: Wait,
    /// Axis name.
    pub axis: &'static str,
    /// The command.
    pub command: Command,
    /// Name of the step (for `Wait::Done` and the log).
    pub label: &'static str,
    /// What the step shows, printed when it is issued.
    pub says: &'static str,
}

/// The demo's axes: `x` linear S-curve, `y` linear trapezoid, `c` rotary modulo 360° with
/// Sine ramps.
pub fn axes() -> Vec<AxisConfig> {
    let mut x = AxisConfig::new("x", AxisKind::Simulated);
    x.max = Limits {
        vmax: 200.0,
        amax: 2000.0,
        dmax: 2000.0,
        jmax: 20_000.0,
    };
    x.defaults.speed = 100.0;
    x.defaults.acceleration = 500.0;
    x.defaults.deceleration = 500.0;
    x.defaults.jerk = 5_000.0;
    x.defaults.ramp = RampType::SCurve;
    x.mechanics.software_limits = Some((-10.0, 400.0));

    let mut y = x.clone();
    y.name = "y".into();
    y.defaults.ramp = RampType::Trapezoid;
    y.defaults.speed = 80.0;
    y.defaults.acceleration = 300.0;
    y.defaults.deceleration = 300.0;

    let mut c = AxisConfig::new("c", AxisKind::Simulated);
    c.mechanics.kind = MotionKind::Rotary;
    c.mechanics.modulo = Modulo::new(360.0);
    c.max = Limits {
        vmax: 720.0,
        amax: 3600.0,
        dmax: 3600.0,
        jmax: 36_000.0,
    };
    c.defaults.speed = 360.0;
    c.defaults.acceleration = 1440.0;
    c.defaults.deceleration = 1440.0;
    c.defaults.jerk = 14_400.0;
    c.defaults.ramp = RampType::Sine;
    vec![x, y, c]
}

const fn ptp(mode: PositioningMode, target: f64) -> Command {
    Command::MovePtp(MovePtp::new(mode, target))
}

/// The scripted sequence.
pub fn script() -> Vec<Step> {
    use PositioningMode::*;
    let step = |wait, axis, command, label, says| Step {
        wait,
        axis,
        command,
        label,
        says,
    };
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
            Wait::Now,
            "x",
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
            "x-home",
            "set reference (homed)",
        ),
        step(
            Wait::Now,
            "y",
            Command::SetPosition {
                position: 0.0,
                relative: false,
            },
            "y-home",
            "",
        ),
        step(
            Wait::Now,
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

/// Runs the demo.
pub fn run(args: &DemoArgs, out: &mut impl Write) -> Result<DemoReport, DemoError> {
    let configs = axes();
    let names: Vec<&'static str> = vec!["x", "y", "c"];
    let mut kernel = Kernel::new(args.cycle_s, configs)?;
    let channels = names
        .iter()
        .flat_map(|n| ["p", "v", "a"].map(|q| format!("{n}.{q}")))
        .collect();
    let mut trace = Trace::new(channels, (TIME_LIMIT_S / args.cycle_s) as usize / 4);
    let mut handles: HashMap<&'static str, HandleId> = HashMap::new();
    let mut last_cmd: Vec<Option<HandleId>> = vec![None; names.len()];
    let mut live = Live::new(std::io::stdout().is_terminal());
    let started = Instant::now();
    let mut next_frame = 0.0;
    let index = |axis: &'static str| {
        names
            .iter()
            .position(|n| *n == axis)
            .ok_or(DemoError::Script(axis))
    };
    let mut sample = vec![0.0; names.len() * 3];
    let mut step_once = |kernel: &mut Kernel,
                         trace: &mut Trace,
                         last_cmd: &[Option<HandleId>],
                         next_frame: &mut f64,
                         out: &mut dyn Write|
     -> Result<(), DemoError> {
        kernel.step(&[]);
        for (i, _) in names.iter().enumerate() {
            let s = kernel.axis_status(i).map(|s| s.set).unwrap_or_default();
            let turns = kernel.axis_status(i).map(|s| s.turns).unwrap_or(0);
            let period = kernel.axes()[i]
                .config()
                .mechanics
                .modulo
                .map(|m| m.period());
            // Modulo axes are traced unwrapped so the plot shows the travel.
            sample[i * 3] = s.p + period.map(|p| turns as f64 * p).unwrap_or(0.0);
            sample[i * 3 + 1] = s.v;
            sample[i * 3 + 2] = s.a;
        }
        trace.push(kernel.time(), &sample)?;
        if kernel.time() + 1e-9 >= *next_frame {
            *next_frame += FRAME_S;
            let rows: Vec<Row> = names
                .iter()
                .enumerate()
                .map(|(i, n)| {
                    let status = kernel.axis_status(i).copied().unwrap_or_default();
                    let cmd = last_cmd[i].map(|h| kernel.command_status(h));
                    Row {
                        axis: (*n).into(),
                        status,
                        command: cmd.map(|c| c.name().to_string()).unwrap_or_default(),
                        error: status.error.map(|e| e.to_string()).unwrap_or_default(),
                    }
                })
                .collect();
            let frame = status_table::render(kernel.time(), &rows);
            let _ = out.write_all(live.frame(&frame).as_bytes());
            let _ = out.flush();
            if args.speed > 0.0 {
                let due = Duration::from_secs_f64(kernel.time() / args.speed);
                if let Some(wait) = due.checked_sub(started.elapsed()) {
                    std::thread::sleep(wait);
                }
            }
        }
        Ok(())
    };
    let limit = (TIME_LIMIT_S / args.cycle_s) as u64;
    for step in script() {
        // Wait for the step's condition.
        let waited_from = kernel.time();
        loop {
            let ready = match step.wait {
                Wait::Now => true,
                Wait::Seconds(s) => kernel.time() - waited_from >= s - 1e-9,
                Wait::Done(label) => {
                    let h = handles.get(label).ok_or(DemoError::Script(label))?;
                    kernel.command_status(*h).is_final()
                }
            };
            if ready {
                break;
            }
            if kernel.tick() > limit {
                return Err(DemoError::Timeout(step.label));
            }
            step_once(&mut kernel, &mut trace, &last_cmd, &mut next_frame, out)?;
        }
        let axis = index(step.axis)?;
        let h = kernel
            .command(axis, step.command)
            .map_err(|error| DemoError::Step {
                label: step.label,
                axis: step.axis,
                command: step.command.name(),
                error,
            })?;
        if !step.says.is_empty() {
            let _ = writeln!(out, ">> {}", step.says);
        }
        handles.insert(step.label, h);
        last_cmd[axis] = Some(h);
    }
    // Let the last moves finish, then a short tail.
    while last_cmd
        .iter()
        .flatten()
        .any(|h| !kernel.command_status(*h).is_final())
    {
        if kernel.tick() > limit {
            return Err(DemoError::Timeout("final moves"));
        }
        step_once(&mut kernel, &mut trace, &last_cmd, &mut next_frame, out)?;
    }
    for (i, h) in last_cmd.iter().enumerate() {
        if let Some(CommandStatus::Error(error)) = h.map(|h| kernel.command_status(h)) {
            return Err(DemoError::Step {
                label: "final",
                axis: names[i],
                command: "last command",
                error,
            });
        }
    }
    for _ in 0..((0.3 / args.cycle_s) as usize) {
        step_once(&mut kernel, &mut trace, &last_cmd, &mut next_frame, out)?;
    }
    std::fs::create_dir_all(&args.out).map_err(|source| DemoError::Io {
        path: args.out.display().to_string(),
        source,
    })?;
    let csv = args.out.join("trace.csv");
    let svg = args.out.join("plot.svg");
    trace.write_csv(&csv)?;
    let panel = |title: &str, q: usize| Panel {
        title: title.into(),
        channels: (0..names.len()).map(|i| i * 3 + q).collect(),
    };
    let doc = plot::svg(
        &trace,
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
    Ok(DemoReport {
        csv,
        svg,
        simulated_s: kernel.time(),
        cycles: kernel.tick(),
        cycle_s: args.cycle_s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let csv = std::fs::read_to_string(&report.csv).unwrap();
        assert_eq!(csv.lines().count() as u64, report.cycles + 1);
        let svg = std::fs::read_to_string(&report.svg).unwrap();
        assert_eq!(svg.matches("<polyline").count(), 9);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
