//! The `gantry` command line.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use clap::{Parser, Subcommand};
use gantry::service::protocol::{
    BufferMode, CamStartMode, CircularDirection, CircularMode, CommissionKind, DriveHomeParams,
    GroupOp, HomeMode, HomeParams, HomeSwitches, JogDirection, LockDirection, MasterSource,
    MoveMode, Request as Line, StepDirection, StepSwitchMode, StepSwitchParams, TransitionMode,
};
use gantry::service::{self, server, RunArgs};
use gantry_cli::client::{self, Client};
use gantry_cli::demo::{self, DemoArgs};
use gantry_cli::profile::{self, Request};
use gantry_cli::scan;
use gantry_cli::sdo::{self as sdo_cli, SdoType, Target};
use gantry_cli::simulator::{SimLink, Simulator};

/// Options of the commands that talk to a running gantry.
#[derive(clap::Args, Debug)]
struct ClientOpts {
    /// Control socket of the running gantry.
    #[arg(long)]
    socket: Option<PathBuf>,
    /// Print JSON for scripts.
    #[arg(long)]
    json: bool,
}

impl ClientOpts {
    fn connect(&self) -> anyhow::Result<Client> {
        let path = self.socket.clone().unwrap_or_else(server::default_socket);
        Ok(Client::connect(&path)?)
    }
}

/// A one-axis command of the command line, as the request it sends.
struct AxisCommand {
    /// What goes on the socket.
    request: Line,
    /// Return at once with the handle instead of waiting for the command to finish.
    no_wait: bool,
    /// Where and how.
    opts: ClientOpts,
}

impl AxisCommand {
    /// The request of a one-axis command; options that do not go together refused.
    fn of(cmd: AxisCmd) -> Result<Self, String> {
        let (request, no_wait, opts) = match cmd {
            AxisCmd::Enable { axis, client } => (Line::Enable { axis }, false, client),
            AxisCmd::Disable { axis, client } => (Line::Disable { axis }, false, client),
            AxisCmd::Move {
                axis,
                to,
                mode,
                speed,
                acceleration,
                deceleration,
                jerk,
                buffer,
                no_wait,
                client,
            } => (
                Line::Move {
                    axis,
                    to,
                    mode,
                    speed,
                    acceleration,
                    deceleration,
                    jerk,
                    buffer,
                },
                no_wait,
                client,
            ),
            AxisCmd::Home {
                axis,
                params,
                no_wait,
                client,
            } => (params.request(axis)?, no_wait, client),
            // A jog runs until halted: nothing to wait for.
            AxisCmd::Jog {
                axis,
                direction,
                speed,
                master,
                lock,
                lock_position,
                client,
            } => (
                Line::Jog {
                    axis,
                    direction,
                    speed,
                    master,
                    lock,
                    lock_position,
                },
                true,
                client,
            ),
            // A gear runs until geared out: nothing to wait for (the status shows InGear).
            AxisCmd::Gear { axis, args, client } => (args.request(axis)?, true, client),
            AxisCmd::Halt { axis, client } => (Line::Halt { axis }, false, client),
            AxisCmd::Stop { axis, client } => (Line::Stop { axis }, false, client),
            AxisCmd::Release { axis, client } => (Line::Release { axis }, false, client),
            AxisCmd::SetPosition {
                axis,
                position,
                client,
            } => (Line::SetPosition { axis, position }, false, client),
            AxisCmd::Reset { axis, client } => (Line::Reset { axis }, false, client),
        };
        Ok(Self {
            request,
            no_wait,
            opts,
        })
    }

    /// Sends the command and waits for it (or not).
    fn send(&self) -> anyhow::Result<()> {
        let mut c = self.opts.connect()?;
        client::command(
            &mut c,
            self.request.axis().unwrap_or_default(),
            &self.request,
            self.no_wait,
            self.opts.json,
            &mut std::io::stdout(),
        )?;
        Ok(())
    }
}

/// gantry: a Linux motion master for CiA-402 drives.
#[derive(Parser, Debug)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Run the scripted demo: simulated CiA-402 drives on an in-process EtherCAT network
    /// (or CANopen with --bus canopen), brought up and driven by gantry's engine; prints
    /// the bus, writes a trace (CSV) and a plot (SVG).
    Demo {
        /// Folder for the demo's configuration, trace.csv, plot.svg and the drives' records.
        #[arg(long, default_value = "out/demo")]
        out: PathBuf,
        /// Simulated seconds per wall-clock second (0: as fast as possible).
        #[arg(long, default_value_t = 4.0)]
        speed: f64,
        /// `ethercat`: simulated CiA-402 drives on an in-process EtherCAT network, brought
        /// up and driven by the master; `canopen`: four simulated CiA-402 drives as CANopen
        /// nodes on an in-memory CAN bus at 1 Mbit/s (2 ms cycle); `none`: the same engine
        /// on simulated axes (actual = set), no bus hardware.
        #[arg(long, default_value = "ethercat", value_parser = ["ethercat", "canopen", "none"])]
        bus: String,
        /// Write every EtherCAT frame sent and received to this pcap file.
        #[arg(long)]
        pcap: Option<PathBuf>,
    },
    /// List the EtherCAT slaves on a network interface (needs CAP_NET_RAW).
    Scan {
        /// Network interface wired to the slaves.
        #[arg(long)]
        interface: String,
        /// Print JSON (one array) instead of a table.
        #[arg(long)]
        json: bool,
        /// Write every frame sent and received to this pcap file.
        #[arg(long)]
        pcap: Option<String>,
    },
    /// Run a configuration as a service with a control socket (see deploy/examples).
    Run {
        /// Configuration file (TOML).
        #[arg(long)]
        config: String,
        /// Run without real-time scheduling (when the capabilities are missing); says so.
        #[arg(long)]
        no_rt: bool,
        /// Control socket path (default: $XDG_RUNTIME_DIR/gantry.sock or /tmp/gantry-UID.sock).
        #[arg(long)]
        socket: Option<PathBuf>,
    },
    /// Axes, drives, bus and cycle figures of a running gantry.
    Status {
        #[command(flatten)]
        client: ClientOpts,
    },
    /// The commands to one axis.
    #[command(flatten)]
    Axis(AxisCmd),
    /// Commission an axis (seed 000 §5.2.6): measure its motor's commutation offset and
    /// write it to the drive, or run the reversing test motion. Shows the progress; Ctrl-C
    /// or `gantry stop AXIS` cancels, leaving the axis stopped and the drive's current off.
    Commission {
        /// The axis.
        axis: String,
        #[command(subcommand)]
        what: CommissionWhat,
    },
    /// Record set and actual positions of axes, to CSV or SVG (by extension).
    Trace {
        /// Axis names.
        #[arg(required_unless_present = "xy")]
        axes: Vec<String>,
        /// Two axes plotted against each other (an .svg of the path in the X-Y plane, set
        /// and actual; equal scales): `--xy x y`.
        #[arg(long, num_args = 2, value_names = ["X", "Y"], conflicts_with = "axes")]
        xy: Option<Vec<String>>,
        /// Seconds to record (up to 60).
        #[arg(long, default_value_t = 5.0, value_parser = finite)]
        seconds: f64,
        /// Output file (.csv or .svg).
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Read (upload) or write (download) an object of a drive while `gantry run` runs:
    /// the transfer goes beside the process data, which keeps running.
    Sdo {
        #[command(subcommand)]
        op: SdoOp,
    },
    /// Axis groups (`[[group]]`): enable, disable, stop, release, reset; coordinated
    /// linear and circular moves (PLCopen MC_MoveLinear, MC_MoveCircular2D).
    Group {
        #[command(subcommand)]
        op: GroupSub,
    },
    /// Cam tables of a running gantry: load one, list them.
    Cam {
        #[command(subcommand)]
        op: CamOp,
    },
    /// Write the DCF (CiA 306) of what the bring-up configures on an axis' CANopen node:
    /// its EDS (the axis' eds, or the simulated node's) with the node id, bit rate and
    /// every object the bring-up writes. Offline: no bus needed.
    Dcf {
        /// Configuration file (TOML).
        #[arg(long)]
        config: String,
        /// The axis whose node it is.
        #[arg(long)]
        axis: String,
        /// Where to write the DCF.
        #[arg(long)]
        out: PathBuf,
    },
    /// Check this machine for real-time use and measure the cycle's wake-up latency
    /// (beside cyclictest when rt-tests is installed).
    RtCheck {
        /// Take priority, CPU and interface from this configuration.
        #[arg(long)]
        config: Option<String>,
        /// Cycle time to measure at (µs; default: the configuration's, else 1000).
        #[arg(long)]
        cycle_us: Option<u32>,
        /// Seconds to measure (each of gantry and cyclictest).
        #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
        seconds: f64,
        /// Measure instead when a CANopen cycle thread hands each SYNC to its link, with
        /// this many simulated servos (in memory, at 1 Mbit/s: no CAN hardware needed),
        /// beside cyclictest on the same CPU.
        #[arg(long, value_name = "DRIVES")]
        can: Option<u8>,
    },
    /// Print the planned profile of one move as JSON.
    Profile {
        /// Start position.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        from_pos: f64,
        /// Start velocity.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        from_vel: f64,
        /// Start acceleration.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        from_acc: f64,
        /// Target position.
        #[arg(long, allow_negative_numbers = true, required_unless_present = "batch")]
        to_pos: Option<f64>,
        /// Maximum speed.
        #[arg(long, allow_negative_numbers = true, required_unless_present = "batch")]
        vmax: Option<f64>,
        /// Maximum acceleration.
        #[arg(long, allow_negative_numbers = true, required_unless_present = "batch")]
        amax: Option<f64>,
        /// Maximum deceleration (default: amax).
        #[arg(long, allow_negative_numbers = true)]
        dmax: Option<f64>,
        /// Maximum jerk (S-curve).
        #[arg(long, allow_negative_numbers = true)]
        jmax: Option<f64>,
        /// scurve, trapezoid, sine or linear-sine.
        #[arg(long, default_value = "scurve")]
        ramp: String,
        /// Read one JSON request per line from stdin, write one JSON answer per line.
        #[arg(long)]
        batch: bool,
    },
}

/// What `gantry cam` does.
#[derive(Subcommand, Debug)]
enum CamOp {
    /// Load a cam table from a file (.csv or .toml; read here, sent as points) under a
    /// name: a new name takes a free slot, a known one has its table replaced (refused
    /// while an axis cams on it).
    Load {
        /// The table's name.
        name: String,
        /// The cam file.
        file: PathBuf,
        /// linear, cubic or quintic (default: a TOML file's, else cubic).
        #[arg(long)]
        interpolation: Option<String>,
        /// The table repeats (default: a TOML file's, else not).
        #[arg(long, conflicts_with = "non_periodic")]
        periodic: bool,
        /// The table does not repeat.
        #[arg(long)]
        non_periodic: bool,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// The cam tables loaded: slot, name, points, interpolation, range.
    Tables {
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Cam an axis to a master through a table (PLCopen MC_CamIn). Returns once the cycle
    /// has taken it; `gantry status` shows when it is in sync and each end of profile.
    In {
        /// Axis name (the follower).
        axis: String,
        #[command(flatten)]
        args: Box<CamInArgs>,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// End camming (PLCopen MC_CamOut): the axis goes on at its velocity.
    Out {
        /// Axis name.
        axis: String,
        #[command(flatten)]
        client: ClientOpts,
    },
}

/// What `gantry group` does.
#[derive(Subcommand, Debug)]
enum GroupSub {
    /// MC_GroupEnable: every axis standing still, none in another enabled group.
    Enable {
        /// The group's name.
        group: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// MC_GroupDisable.
    Disable {
        /// The group's name.
        group: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// MC_GroupStop: brake along the path and lock until `gantry group release`.
    Stop {
        /// The group's name.
        group: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// MC_GroupHalt: brake along the path to standstill (no lock: the next move may
    /// follow at once).
    Halt {
        /// The group's name.
        group: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// MC_GroupHome: every axis of the group runs its configured homing, together; waits
    /// until all are homed.
    Home {
        /// The group's name.
        group: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Release a stopped group.
    Release {
        /// The group's name.
        group: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// MC_GroupReset: leave ErrorStop.
    Reset {
        /// The group's name.
        group: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// MC_MoveLinear: the group's axes along a straight line, showing progress.
    Line {
        /// The group's name.
        group: String,
        /// Target of each of the group's axes, A0 first: 10,20 (or distances with
        /// --relative).
        #[arg(long, allow_hyphen_values = true, value_parser = positions)]
        to: Positions,
        #[command(flatten)]
        path: Box<PathArgs>,
    },
    /// MC_MoveCircular2D: an arc in two of the group's axes (A0 and A1 unless --axes),
    /// showing progress.
    Arc {
        /// The group's name.
        group: String,
        /// End point x,y.
        #[arg(long, allow_hyphen_values = true, value_parser = position_xy)]
        end: (f64, f64),
        /// The arc's center x,y.
        #[arg(long, allow_hyphen_values = true, value_parser = position_xy, group = "how")]
        center: Option<(f64, f64)>,
        /// A point x,y the arc passes through.
        #[arg(long, allow_hyphen_values = true, value_parser = position_xy, group = "how")]
        through: Option<(f64, f64)>,
        /// The radius (negative: the long arc).
        #[arg(long, allow_negative_numbers = true, value_parser = finite, group = "how")]
        radius: Option<f64>,
        /// Clockwise (default counter-clockwise).
        #[arg(long)]
        cw: bool,
        /// The two circular axes as logical axes of the group: 0,1.
        #[arg(long, value_parser = logical_pair)]
        axes: Option<(usize, usize)>,
        #[command(flatten)]
        path: Box<PathArgs>,
    },
}

/// What `gantry group line` and `arc` share.
#[derive(clap::Args, Debug)]
struct PathArgs {
    /// Path velocity (units/s, required).
    #[arg(long, value_parser = finite)]
    velocity: f64,
    /// Path acceleration (default: the axes' limits decide).
    #[arg(long, value_parser = finite)]
    acceleration: Option<f64>,
    /// Path deceleration.
    #[arg(long, value_parser = finite)]
    deceleration: Option<f64>,
    /// Path jerk.
    #[arg(long, value_parser = finite)]
    jerk: Option<f64>,
    /// The positions are distances from where the move starts.
    #[arg(long)]
    relative: bool,
    /// How the move joins the group's running one: aborting (on a standing group it
    /// just starts), buffered (starts when it ends), blending-low, blending-previous,
    /// blending-next, blending-high (passes the junction in motion). All but aborting
    /// return at once, so that the next move can be queued.
    #[arg(long, default_value = "aborting")]
    buffer: BufferMode,
    /// The same as --buffer buffered.
    #[arg(long, conflicts_with = "buffer")]
    buffered: bool,
    /// How a blended junction may leave the path: none (only collinear lines are passed
    /// in motion) or corner-superimposed (the corner is rounded).
    #[arg(long, default_value = "none")]
    transition: TransitionMode,
    /// With corner-superimposed: how far the rounded path may pass from the corner
    /// (units, > 0; default the group's corner_deviation, else the axes' limits decide).
    #[arg(long, allow_negative_numbers = true, value_parser = finite)]
    corner_deviation: Option<f64>,
    /// Return at once with the command's handle.
    #[arg(long)]
    no_wait: bool,
    #[command(flatten)]
    client: ClientOpts,
}

impl PathArgs {
    /// The buffer mode asked for (--buffered is --buffer buffered).
    fn buffer(&self) -> BufferMode {
        if self.buffered {
            BufferMode::Buffered
        } else {
            self.buffer
        }
    }

    /// Whether the command returns at once: asked to, or queued behind a running move.
    fn no_wait(&self) -> bool {
        self.no_wait || self.buffer() != BufferMode::Aborting
    }
}

impl GroupSub {
    /// The request, whether to return at once, and where to send it.
    fn command(self) -> Result<AxisCommand, String> {
        let op = |group, op, client| AxisCommand {
            request: Line::Group { group, op },
            no_wait: false,
            opts: client,
        };
        Ok(match self {
            GroupSub::Enable { group, client } => op(group, GroupOp::Enable, client),
            GroupSub::Disable { group, client } => op(group, GroupOp::Disable, client),
            GroupSub::Stop { group, client } => op(group, GroupOp::Stop, client),
            GroupSub::Halt { group, client } => op(group, GroupOp::Halt, client),
            GroupSub::Home { group, client } => op(group, GroupOp::Home, client),
            GroupSub::Release { group, client } => op(group, GroupOp::Release, client),
            GroupSub::Reset { group, client } => op(group, GroupOp::Reset, client),
            GroupSub::Line { group, to, path } => {
                let p = *path;
                AxisCommand {
                    request: Line::MoveLinear {
                        group,
                        to: to.0,
                        velocity: p.velocity,
                        acceleration: p.acceleration,
                        deceleration: p.deceleration,
                        jerk: p.jerk,
                        relative: p.relative,
                        buffer: p.buffer(),
                        transition: p.transition,
                        corner_deviation: p.corner_deviation,
                    },
                    no_wait: p.no_wait(),
                    opts: p.client,
                }
            }
            GroupSub::Arc {
                group,
                end,
                center,
                through,
                radius,
                cw,
                axes,
                path,
            } => {
                let (mode, aux) = match (center, through, radius) {
                    (Some(c), None, None) => (CircularMode::Center, [c.0, c.1]),
                    (None, Some(t), None) => (CircularMode::Border, [t.0, t.1]),
                    (None, None, Some(r)) => (CircularMode::Radius, [r, 0.0]),
                    _ => return Err("arc: give one of --center, --through, --radius".into()),
                };
                let p = *path;
                AxisCommand {
                    request: Line::MoveCircular {
                        group,
                        mode,
                        aux,
                        end: [end.0, end.1],
                        direction: if cw {
                            CircularDirection::Cw
                        } else {
                            CircularDirection::Ccw
                        },
                        axes: axes.map(|(a, b)| [a, b]),
                        velocity: p.velocity,
                        acceleration: p.acceleration,
                        deceleration: p.deceleration,
                        jerk: p.jerk,
                        relative: p.relative,
                        buffer: p.buffer(),
                        transition: p.transition,
                        corner_deviation: p.corner_deviation,
                    },
                    no_wait: p.no_wait(),
                    opts: p.client,
                }
            }
        })
    }
}

/// One to four positions, A0 first (one argument: clap would read a `Vec` as repeats).
#[derive(Clone, Debug, PartialEq)]
struct Positions(Vec<f64>);

/// Positions `a,b[,c[,d]]`.
fn positions(text: &str) -> Result<Positions, String> {
    let v: Vec<f64> = text
        .split(',')
        .map(|p| finite(p.trim()))
        .collect::<Result<_, _>>()?;
    if v.is_empty() || v.len() > 4 {
        return Err(format!("{text:?}: one to four positions, comma-separated"));
    }
    Ok(Positions(v))
}

/// A point `x,y`.
fn position_xy(text: &str) -> Result<(f64, f64), String> {
    let (a, b) = text
        .split_once(',')
        .ok_or_else(|| format!("{text:?} is not x,y"))?;
    Ok((finite(a.trim())?, finite(b.trim())?))
}

/// Two logical axes `a,b`.
fn logical_pair(text: &str) -> Result<(usize, usize), String> {
    let (a, b) = text
        .split_once(',')
        .ok_or_else(|| format!("{text:?} is not two logical axes a,b (0 to 3)"))?;
    let n = |s: &str| {
        s.trim()
            .parse::<usize>()
            .map_err(|_| format!("{s:?} is not a logical axis (0 to 3)"))
    };
    Ok((n(a)?, n(b)?))
}

/// `gantry cam in`'s arguments.
#[derive(clap::Args, Debug)]
struct CamInArgs {
    /// The master axis.
    #[arg(long)]
    master: String,
    /// The cam table's name (`gantry cam tables`).
    #[arg(long)]
    table: String,
    /// Run through the table once (EndOfProfile at its end), not periodically.
    #[arg(long)]
    once: bool,
    /// Start the table where the master is and add it to the axis' position (PLCopen
    /// relative); default absolute: the table's axes are the master's and the axis'
    /// positions.
    #[arg(long)]
    relative: bool,
    /// Follow the master's actual values (its encoder) instead of its set values.
    #[arg(long)]
    actual: bool,
    /// Shift of the table's master coordinate.
    #[arg(long, allow_negative_numbers = true, value_parser = finite)]
    master_offset: Option<f64>,
    /// Shift of the axis (its units).
    #[arg(long, allow_negative_numbers = true, value_parser = finite)]
    slave_offset: Option<f64>,
    /// Table master units per master unit.
    #[arg(long, allow_negative_numbers = true, value_parser = finite)]
    master_scaling: Option<f64>,
    /// Axis units per table slave unit.
    #[arg(long, allow_negative_numbers = true, value_parser = finite)]
    slave_scaling: Option<f64>,
    #[command(flatten)]
    catch_up: CatchUpArgs,
}

impl CamInArgs {
    fn request(&self, axis: String) -> Line {
        Line::Cam {
            axis,
            master: self.master.clone(),
            table: self.table.clone(),
            periodic: self.once.then_some(false),
            start: self.relative.then_some(CamStartMode::Relative),
            source: self.actual.then_some(MasterSource::Actual),
            master_offset: self.master_offset,
            slave_offset: self.slave_offset,
            master_scaling: self.master_scaling,
            slave_scaling: self.slave_scaling,
            acceleration: self.catch_up.acceleration,
            deceleration: self.catch_up.deceleration,
            jerk: self.catch_up.jerk,
        }
    }
}

/// What `gantry commission` does.
#[derive(Subcommand, Debug)]
enum CommissionWhat {
    /// Measure the commutation offset in the dynamic mode (small motion: about one
    /// electrical revolution each way) and write it to the drive. The axis must be
    /// disabled (a drive of unknown commutation cannot hold its motor) and is left so.
    Commutation {
        /// Current of the measurement (per mille of the motor's rated current).
        #[arg(long, value_parser = clap::value_parser!(u16).range(1..=3000))]
        current: Option<u16>,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Move back and forth between two positions (point-to-point, the axis' last-used
    /// speed and ramps unless --speed), to tune the loops.
    Reversing {
        /// One end (the axis' units); the motion starts by moving here.
        #[arg(long, allow_negative_numbers = true, value_parser = finite)]
        from: f64,
        /// The other end.
        #[arg(long, allow_negative_numbers = true, value_parser = finite)]
        to: f64,
        /// Cycles there and back.
        #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
        cycles: u32,
        /// Speed (units/s).
        #[arg(long, value_parser = finite)]
        speed: Option<f64>,
        #[command(flatten)]
        client: ClientOpts,
    },
}

/// Set by SIGINT while `gantry commission` runs.
static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

extern "C" fn on_sigint(_: nix::libc::c_int) {
    INTERRUPTED.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// `gantry home`'s parameters (each left out is the axis' saved one: the last call's, kept
/// across restarts when the service has a state directory).
#[derive(clap::Args, Debug)]
struct HomeArgs {
    /// Search direction. MoveHome: + or - (or positive, negative). --step-to-switch
    /// (Direction): positive, negative, switch-positive or switch-negative (these two
    /// first leave the cam when they start on it).
    #[arg(long, allow_hyphen_values = true)]
    direction: Option<String>,
    /// ref-and-limit, ref, limit or none (the index pulse only).
    #[arg(long, help_heading = "MoveHome (the default)")]
    switches: Option<HomeSwitches>,
    /// edge, edge-2 (switch fast, edge slowly), zero-pulse, zero-pulse-2.
    #[arg(long, help_heading = "MoveHome (the default)")]
    mode: Option<HomeMode>,
    /// Speed of the switch search (units/s).
    #[arg(long, value_parser = finite, help_heading = "MoveHome (the default)")]
    speed_switch: Option<f64>,
    /// Longest switch search (units).
    #[arg(long, value_parser = finite, help_heading = "MoveHome (the default)")]
    max_distance_switch: Option<f64>,
    /// Speed of the reference search (units/s).
    #[arg(long, value_parser = finite, help_heading = "MoveHome (the default)")]
    speed_reference: Option<f64>,
    /// Longest reference search (units).
    #[arg(long, value_parser = finite, help_heading = "MoveHome (the default)")]
    max_distance_reference: Option<f64>,
    /// Acceleration (units/s²), of MoveHome and --step-to-switch (--drive: its homing
    /// acceleration).
    #[arg(long, value_parser = finite)]
    acceleration: Option<f64>,
    /// Jerk (units/s³), of MoveHome and --step-to-switch.
    #[arg(long, value_parser = finite)]
    jerk: Option<f64>,
    /// The position the reference gets (units).
    #[arg(long, allow_negative_numbers = true, value_parser = finite, help_heading = "MoveHome (the default)")]
    reference_offset: Option<f64>,
    /// Where the axis goes after homing (units).
    #[arg(long, allow_negative_numbers = true, value_parser = finite, help_heading = "MoveHome (the default)")]
    normal_position: Option<f64>,
    /// Run Jetter MoveHome (its saved parameters for what is left out) when the axis'
    /// last homing was step-to-switch; any MoveHome option says so too.
    #[arg(long, conflicts_with_all = ["step_to_switch", "drive"], help_heading = "MoveHome (the default)")]
    move_home: bool,
    /// Beckhoff step-to-absolute-switch (MC_StepAbsoluteSwitch): search the reference cam,
    /// reversing at the limit switches; the crossing --switch-mode names gets
    /// --set-position, and the axis stops just past it. Takes --direction, --switch-mode,
    /// --velocity (these three are required on the axis' first call), --acceleration,
    /// --deceleration, --jerk (default: the axis' defaults), --set-position (default 0)
    /// and --distance-limit (default: none, only the limit switches).
    #[arg(
        long,
        conflicts_with = "drive",
        help_heading = "Step to absolute switch (--step-to-switch)"
    )]
    step_to_switch: bool,
    /// --step-to-switch (SwitchMode): which crossing of the cam ends the run: on, off,
    /// rising-edge, falling-edge (moving in --direction), rising-edge-inverse,
    /// falling-edge-inverse (moving against it), edge-switch-positive (the cam's
    /// negative edge), edge-switch-negative (its positive edge).
    #[arg(long, help_heading = "Step to absolute switch (--step-to-switch)")]
    switch_mode: Option<StepSwitchMode>,
    /// --step-to-switch (Velocity): search speed (units/s).
    #[arg(long, value_parser = finite, help_heading = "Step to absolute switch (--step-to-switch)")]
    velocity: Option<f64>,
    /// --step-to-switch (Deceleration): units/s²; also how hard the search reverses.
    #[arg(long, value_parser = finite, help_heading = "Step to absolute switch (--step-to-switch)")]
    deceleration: Option<f64>,
    /// --step-to-switch (SetPosition): the position the cam's crossing gets (units).
    #[arg(long, allow_negative_numbers = true, value_parser = finite, help_heading = "Step to absolute switch (--step-to-switch)")]
    set_position: Option<f64>,
    /// --step-to-switch (DistanceLimit): farthest the search may travel (units).
    #[arg(long, value_parser = finite, help_heading = "Step to absolute switch (--step-to-switch)")]
    distance_limit: Option<f64>,
    /// Let the drive home itself (CiA 402 homing mode) with `[axis.drive_homing]`; the
    /// options below (and --speed-switch, --acceleration) replace its values.
    #[arg(long, help_heading = "Drive homing (--drive)")]
    drive: bool,
    /// --drive: the CiA 402 homing method (0x6098).
    #[arg(
        long,
        allow_negative_numbers = true,
        help_heading = "Drive homing (--drive)"
    )]
    method: Option<i8>,
    /// --drive: speed during search for zero (units/s).
    #[arg(long, value_parser = finite, help_heading = "Drive homing (--drive)")]
    speed_zero: Option<f64>,
    /// --drive: home offset (units; the home position reads as minus this).
    #[arg(long, allow_negative_numbers = true, value_parser = finite, help_heading = "Drive homing (--drive)")]
    home_offset: Option<f64>,
    /// --drive: how long the drive may take to report homing attained (s).
    #[arg(long, value_parser = finite, help_heading = "Drive homing (--drive)")]
    timeout: Option<f64>,
    /// --drive: skip the drive's homing run (an absolute drive): homed where it stands.
    #[arg(long, help_heading = "Drive homing (--drive)")]
    skip: bool,
}

impl HomeArgs {
    /// The options of one homing run given, by name.
    fn given(&self, which: Only) -> Vec<&'static str> {
        let all: Vec<(&'static str, bool)> = match which {
            Only::MoveHome => vec![
                ("--switches", self.switches.is_some()),
                ("--mode", self.mode.is_some()),
                ("--max-distance-switch", self.max_distance_switch.is_some()),
                ("--speed-reference", self.speed_reference.is_some()),
                (
                    "--max-distance-reference",
                    self.max_distance_reference.is_some(),
                ),
                ("--reference-offset", self.reference_offset.is_some()),
                ("--normal-position", self.normal_position.is_some()),
            ],
            Only::StepToSwitch => vec![
                ("--switch-mode", self.switch_mode.is_some()),
                ("--velocity", self.velocity.is_some()),
                ("--deceleration", self.deceleration.is_some()),
                ("--set-position", self.set_position.is_some()),
                ("--distance-limit", self.distance_limit.is_some()),
            ],
            Only::Drive => vec![
                ("--method", self.method.is_some()),
                ("--speed-zero", self.speed_zero.is_some()),
                ("--home-offset", self.home_offset.is_some()),
                ("--timeout", self.timeout.is_some()),
                ("--skip", self.skip),
            ],
        };
        all.into_iter()
            .filter(|(_, given)| *given)
            .map(|(name, _)| name)
            .collect()
    }

    /// The request: drive homing with --drive, step-to-absolute-switch with
    /// --step-to-switch, MoveHome with --move-home or any of its options, else the axis'
    /// last homing run (MoveHome or step-to-switch) with its saved parameters. An option
    /// of another homing run is refused by name.
    fn request(self, axis: String) -> Result<Line, String> {
        let refuse = |which: Only, why: &str| match self.given(which).first() {
            Some(name) => Err(format!("{name} {why}")),
            None => Ok(()),
        };
        if self.drive {
            refuse(
                Only::StepToSwitch,
                "is a step-to-switch option; the drive homes by its method (--method)",
            )?;
            if self.direction.is_some() {
                return Err(
                    "--direction is a MoveHome option; the drive homes by its method (--method)"
                        .into(),
                );
            }
            refuse(
                Only::MoveHome,
                "is a MoveHome option; the drive homes by its method (--method)",
            )?;
            if self.jerk.is_some() {
                return Err(
                    "--jerk is a MoveHome option; the drive homes by its method (--method)".into(),
                );
            }
            return Ok(Line::DriveHome {
                axis,
                params: DriveHomeParams {
                    method: self.method,
                    speed_switch: self.speed_switch,
                    speed_zero: self.speed_zero,
                    acceleration: self.acceleration,
                    home_offset: self.home_offset,
                    timeout_s: self.timeout,
                    skip: self.skip.then_some(true),
                },
            });
        }
        refuse(Only::Drive, "is a drive homing option (--drive)")?;
        if self.step_to_switch {
            refuse(
                Only::MoveHome,
                "is a MoveHome option, not one of step-to-switch's",
            )?;
            if self.speed_switch.is_some() {
                return Err(
                    "--speed-switch is a MoveHome option; step-to-switch searches at --velocity"
                        .into(),
                );
            }
            let direction = self
                .direction
                .as_deref()
                .map(str::parse::<StepDirection>)
                .transpose()
                .map_err(|e| format!("--direction: {e}"))?;
            return Ok(Line::Home {
                axis,
                params: None,
                step_switch: Some(StepSwitchParams {
                    direction,
                    switch_mode: self.switch_mode,
                    velocity: self.velocity,
                    acceleration: self.acceleration,
                    deceleration: self.deceleration,
                    jerk: self.jerk,
                    set_position: self.set_position,
                    distance_limit: self.distance_limit,
                }),
            });
        }
        refuse(
            Only::StepToSwitch,
            "is a step-to-switch option (--step-to-switch)",
        )?;
        let direction = self
            .direction
            .as_deref()
            .map(str::parse::<JogDirection>)
            .transpose()
            .map_err(|e| format!("--direction: {e} (MoveHome; with --step-to-switch also switch-positive, switch-negative)"))?;
        let params = HomeParams {
            direction,
            switches: self.switches,
            mode: self.mode,
            speed_switch: self.speed_switch,
            max_distance_switch: self.max_distance_switch,
            speed_reference: self.speed_reference,
            max_distance_reference: self.max_distance_reference,
            acceleration: self.acceleration,
            jerk: self.jerk,
            reference_offset: self.reference_offset,
            normal_position: self.normal_position,
        };
        // Nothing of MoveHome's given: the axis' last homing run, whichever it was.
        let params = (self.move_home || params != HomeParams::default()).then_some(params);
        Ok(Line::Home {
            axis,
            params,
            step_switch: None,
        })
    }
}

/// The homing run some options belong to (and to no other).
#[derive(Clone, Copy)]
enum Only {
    MoveHome,
    StepToSwitch,
    Drive,
}

/// The commands to one axis of a running gantry.
#[derive(Subcommand, Debug)]
enum AxisCmd {
    /// Power an axis on.
    Enable {
        /// Axis name.
        axis: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Power an axis off (stopping it first).
    Disable {
        /// Axis name.
        axis: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Move an axis (point to point), showing progress.
    Move {
        /// Axis name.
        axis: String,
        /// Target (or distance with --mode relative), in the axis' units.
        #[arg(long, allow_negative_numbers = true, value_parser = finite)]
        to: f64,
        /// absolute or relative; on a modulo axis also shortest, positive or negative
        /// (the way round).
        #[arg(long, default_value = "absolute")]
        mode: MoveMode,
        /// Speed (units/s; default: the axis' default).
        #[arg(long, allow_negative_numbers = true, value_parser = finite)]
        speed: Option<f64>,
        /// Acceleration (units/s²).
        #[arg(long, allow_negative_numbers = true, value_parser = finite)]
        acceleration: Option<f64>,
        /// Deceleration (units/s²).
        #[arg(long, allow_negative_numbers = true, value_parser = finite)]
        deceleration: Option<f64>,
        /// Jerk (units/s³).
        #[arg(long, allow_negative_numbers = true, value_parser = finite)]
        jerk: Option<f64>,
        /// aborting, buffered, blending-low, blending-previous, blending-next, blending-high.
        #[arg(long, default_value = "aborting")]
        buffer: BufferMode,
        /// Return at once with the command's handle.
        #[arg(long)]
        no_wait: bool,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Home an axis on its switches and its drive's touch probe, showing the phases: Jetter
    /// MoveHome, or with --step-to-switch Beckhoff step-to-absolute-switch. What is left
    /// out is the axis' saved parameters (the last call's, kept across restarts in the
    /// state directory), and `gantry home AXIS` alone repeats the axis' last homing run of
    /// these two (MoveHome when it has had none; --move-home or --step-to-switch choose).
    /// With --drive the drive homes itself (CiA 402 homing mode, `[axis.drive_homing]`)
    /// and is handed back in CSP; it is never repeated without --drive.
    Home {
        /// Axis name.
        axis: String,
        #[command(flatten)]
        params: Box<HomeArgs>,
        /// Return at once with the command's handle.
        #[arg(long)]
        no_wait: bool,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Jog an axis until halted.
    Jog {
        /// Axis name.
        axis: String,
        /// + or - (or positive, negative).
        #[arg(long, allow_hyphen_values = true)]
        direction: JogDirection,
        /// Speed (units/s; with --master, units per master unit).
        #[arg(long, allow_negative_numbers = true, value_parser = finite)]
        speed: f64,
        /// Drive the jog by this master axis (Logix MAJ with MDAC): the axis moves --speed
        /// of its units per master unit while the lock holds.
        #[arg(long)]
        master: Option<String>,
        /// When a master-driven jog follows: none (both ways, from the start),
        /// immediate-forward, immediate-reverse, position-forward, position-reverse.
        #[arg(long, requires = "master")]
        lock: Option<LockDirection>,
        /// The master position of the position-* locks.
        #[arg(long, requires = "master", allow_negative_numbers = true, value_parser = finite)]
        lock_position: Option<f64>,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Gear an axis to a master at a ratio (PLCopen MC_GearIn; with --sync in sync at given
    /// positions, MC_GearInPos), or end the gearing with --out (MC_GearOut: the axis goes
    /// on at its velocity). Returns at once; `gantry status` shows InGear.
    Gear {
        /// Axis name (the follower).
        axis: String,
        #[command(flatten)]
        args: Box<GearArgs>,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Decelerate an axis to a stop.
    Halt {
        /// Axis name.
        axis: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Stop an axis and lock it until released (`gantry release`).
    Stop {
        /// Axis name.
        axis: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Release a stopped axis.
    Release {
        /// Axis name.
        axis: String,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Set an axis' position without moving (homing by "set position"; marks it homed).
    SetPosition {
        /// Axis name.
        axis: String,
        /// The position the axis is at now, in its units.
        #[arg(long, allow_negative_numbers = true, value_parser = finite)]
        position: f64,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Reset an axis in ErrorStop (its slave back to OP, the drive's fault reset).
    Reset {
        /// Axis name.
        axis: String,
        #[command(flatten)]
        client: ClientOpts,
    },
}

/// Which drive an SDO transfer goes to: by axis, by bus position or by CANopen node id.
#[derive(clap::Args, Debug)]
#[group(required = true, multiple = false)]
struct SdoTarget {
    /// The axis whose drive it is.
    #[arg(long)]
    axis: Option<String>,
    /// The drive's position on the bus (0 is the first slave).
    #[arg(long)]
    drive: Option<usize>,
    /// On CANopen: the drive's node id (1..=127).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=127))]
    node: Option<u8>,
}

impl SdoTarget {
    fn target(self) -> Target {
        match (self.axis, self.drive, self.node) {
            (Some(a), _, _) => Target::Axis(a),
            (None, Some(d), _) => Target::Drive(d),
            (None, None, Some(n)) => Target::Node(n),
            // clap's group requires one of them.
            (None, None, None) => Target::Drive(usize::MAX),
        }
    }
}

/// `gantry sdo upload|download`.
#[derive(Subcommand, Debug)]
enum SdoOp {
    /// Read an object: prints its value as --type, or writes its bytes to --out.
    Upload {
        #[command(flatten)]
        target: SdoTarget,
        /// The object: INDEX:SUB in hex (e.g. 0x6061:0).
        object: String,
        /// u8 u16 u32 u64 i8 i16 i32 i64 f32 string hex (default: the object's type in
        /// the drive's EDS, `[[axis]] eds`; hex bytes for a drive without one).
        #[arg(long = "type", conflicts_with = "out")]
        ty: Option<SdoType>,
        /// Write the object's bytes, as the drive sent them, to this file (a recorder, a
        /// parameter set: up to `[bus] sdo_max_bytes`, 64 KiB by default).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Seconds the drive may take to answer (default 2).
        #[arg(long, value_parser = finite)]
        timeout: Option<f64>,
        #[command(flatten)]
        client: ClientOpts,
    },
    /// Write an object: VALUE as --type, or the bytes of --file.
    Download {
        #[command(flatten)]
        target: SdoTarget,
        /// The object: INDEX:SUB in hex (e.g. 0x6060:0).
        object: String,
        /// The value (decimal or 0x… for integers; hex digits for --type hex).
        #[arg(allow_hyphen_values = true, required_unless_present = "file")]
        value: Option<String>,
        /// u8 u16 u32 u64 i8 i16 i32 i64 f32 string hex (default: the object's type in
        /// the drive's EDS, `[[axis]] eds`; hex bytes for a drive without one).
        #[arg(long = "type", conflicts_with = "file")]
        ty: Option<SdoType>,
        /// Write this file's bytes, as they are, instead of a VALUE (up to `[bus]
        /// sdo_max_bytes`, 64 KiB by default).
        #[arg(long, conflicts_with = "value")]
        file: Option<PathBuf>,
        /// Seconds the drive may take to answer (default 2).
        #[arg(long, value_parser = finite)]
        timeout: Option<f64>,
        #[command(flatten)]
        client: ClientOpts,
    },
}

/// A number that is finite: clap takes "nan" and "inf" for an f64, the axes do not.
/// How a follower catches up with its master (`gantry gear`, `gantry cam in`); left
/// out, the axis' defaults.
#[derive(clap::Args, Debug)]
struct CatchUpArgs {
    /// Catch-up acceleration (units/s²; default the axis').
    #[arg(long, value_parser = finite)]
    acceleration: Option<f64>,
    /// Catch-up deceleration (units/s²).
    #[arg(long, value_parser = finite)]
    deceleration: Option<f64>,
    /// Catch-up jerk (units/s³).
    #[arg(long, value_parser = finite)]
    jerk: Option<f64>,
}

/// `gantry gear`'s arguments.
#[derive(clap::Args, Debug)]
struct GearArgs {
    /// The master axis.
    #[arg(long, required_unless_present = "out")]
    master: Option<String>,
    /// Follower units per master unit as NUMERATOR:DENOMINATOR (3:2, -1:4) or NUMERATOR.
    #[arg(long, required_unless_present = "out", allow_hyphen_values = true, value_parser = ratio)]
    ratio: Option<(i32, u32)>,
    /// Follow the master's actual values (its encoder) instead of its set values.
    #[arg(long)]
    actual: bool,
    #[command(flatten)]
    catch_up: CatchUpArgs,
    /// In sync at MASTER_POSITION:SLAVE_POSITION (MC_GearInPos).
    #[arg(long, allow_hyphen_values = true, value_parser = position_pair)]
    sync: Option<(f64, f64)>,
    /// With --sync: the master distance before its sync position over which the axis
    /// catches up (it stands until then).
    #[arg(long, requires = "sync", value_parser = finite)]
    start_distance: Option<f64>,
    /// End the gearing (MC_GearOut).
    #[arg(long, conflicts_with_all = ["master", "ratio", "actual", "sync"])]
    out: bool,
}

impl GearArgs {
    fn request(&self, axis: String) -> Result<Line, String> {
        if self.out {
            return Ok(Line::GearOut { axis });
        }
        let (Some(master), Some((numerator, denominator))) = (self.master.clone(), self.ratio)
        else {
            return Err("gear: --master and --ratio are needed (or --out)".into());
        };
        Ok(Line::Gear {
            axis,
            master,
            numerator,
            denominator,
            source: self.actual.then_some(MasterSource::Actual),
            acceleration: self.catch_up.acceleration,
            deceleration: self.catch_up.deceleration,
            jerk: self.catch_up.jerk,
            master_sync_position: self.sync.map(|s| s.0),
            slave_sync_position: self.sync.map(|s| s.1),
            master_start_distance: self.start_distance,
        })
    }
}

/// A gear ratio: `N:D` or `N` (D = 1); D > 0, N ≠ 0.
fn ratio(text: &str) -> Result<(i32, u32), String> {
    let (n, d) = text.split_once(':').unwrap_or((text, "1"));
    let n: i32 = n
        .trim()
        .parse()
        .map_err(|_| format!("{text:?}: the numerator {n:?} is not a whole number"))?;
    let d: u32 = d
        .trim()
        .parse()
        .map_err(|_| format!("{text:?}: the denominator {d:?} is not a whole number > 0"))?;
    if d == 0 || n == 0 {
        return Err(format!(
            "{text:?}: numerator and denominator must not be 0 (NUMERATOR:DENOMINATOR, e.g. 3:2)"
        ));
    }
    Ok((n, d))
}

/// Two positions `A:B`.
fn position_pair(text: &str) -> Result<(f64, f64), String> {
    let (a, b) = text
        .split_once(':')
        .ok_or_else(|| format!("{text:?} is not MASTER_POSITION:SLAVE_POSITION"))?;
    Ok((finite(a.trim())?, finite(b.trim())?))
}

fn finite(text: &str) -> Result<f64, String> {
    let value: f64 = text
        .parse()
        .map_err(|_| format!("{text:?} is not a number"))?;
    if value.is_finite() {
        Ok(value)
    } else {
        Err(format!("{text} is not a finite number"))
    }
}

/// `gantry cam …`.
fn cam_command(op: CamOp) -> anyhow::Result<()> {
    match op {
        CamOp::Load {
            name,
            file,
            interpolation,
            periodic,
            non_periodic,
            client: opts,
        } => {
            let periodic = match (periodic, non_periodic) {
                (true, _) => Some(true),
                (_, true) => Some(false),
                _ => None,
            };
            let request =
                gantry_cli::cam::load_request(&name, &file, interpolation.as_deref(), periodic)?;
            let mut c = opts.connect()?;
            gantry_cli::cam::load(&mut c, &request, opts.json, &mut std::io::stdout())?;
        }
        CamOp::Tables { client: opts } => {
            let mut c = opts.connect()?;
            gantry_cli::cam::tables(&mut c, opts.json, &mut std::io::stdout())?;
        }
        op @ (CamOp::In { .. } | CamOp::Out { .. }) => {
            if let Some(c) = cam_axis_command(op) {
                c.send()?;
            }
        }
    }
    Ok(())
}

/// `gantry cam in` / `gantry cam out` as the one-axis command they are (`None` for the
/// table commands). A cam runs until cammed out (or a non-periodic table's end): nothing
/// to wait for but the cycle taking it.
fn cam_axis_command(op: CamOp) -> Option<AxisCommand> {
    match op {
        CamOp::In { axis, args, client } => Some(AxisCommand {
            request: args.request(axis),
            no_wait: true,
            opts: client,
        }),
        CamOp::Out { axis, client } => Some(AxisCommand {
            request: Line::CamOut { axis },
            no_wait: true,
            opts: client,
        }),
        CamOp::Load { .. } | CamOp::Tables { .. } => None,
    }
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    if !matches!(cli.command, Cmd::Run { .. }) {
        // `gantry status | head`: end quietly when the reader goes, as Unix tools do. The
        // service keeps Rust's default (ignored), so a client hanging up cannot kill it.
        // SAFETY: restoring the default disposition, before any thread starts.
        let _ = unsafe {
            nix::sys::signal::signal(
                nix::sys::signal::Signal::SIGPIPE,
                nix::sys::signal::SigHandler::SigDfl,
            )
        };
    }
    match run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // What failed, then each cause after a colon (`{:#}` walks the sources; the
            // errors keep their causes there, not in their messages, so each is said once).
            // No backtrace: it would not help a user.
            eprintln!("gantry: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Cmd::Demo {
            out,
            speed,
            bus,
            pcap,
        } => {
            anyhow::ensure!(
                pcap.is_none() || bus == "ethercat",
                "--pcap needs the EtherCAT demo (--bus {bus} writes no EtherCAT frames)"
            );
            anyhow::ensure!(
                speed.is_finite() && speed >= 0.0,
                "--speed {speed} must be >= 0"
            );
            let args = DemoArgs {
                out,
                speed,
                pcap,
                ..DemoArgs::default()
            };
            let mut stdout = std::io::stdout();
            let report = match bus.as_str() {
                "ethercat" => demo::ethercat::run(&args, &mut stdout)?,
                "canopen" => demo::canopen::run(&args, &mut stdout)?,
                _ => demo::run(&args, &mut stdout)?,
            };
            writeln!(
                stdout,
                "\ndemo done: {:.2} s simulated in {} cycles of {} ms\ntrace: {}\nplot:  {}",
                report.simulated_s,
                report.cycles,
                report.cycle_s * 1e3,
                report.csv.display(),
                report.svg.display()
            )?;
            if let Some(xy) = &report.xy {
                writeln!(stdout, "path:  {}", xy.display())?;
            }
        }
        Cmd::Run {
            config,
            no_rt,
            socket,
        } => {
            let args = RunArgs {
                config,
                no_rt,
                socket: socket.unwrap_or_else(server::default_socket),
            };
            // `[bus] simulator` runs in this process, on a thread of its own.
            let simulator = Arc::new(Simulator::new(SimLink::Thread));
            service::run(&args, simulator, &mut std::io::stdout())?;
        }
        Cmd::Status { client: opts } => {
            let mut c = opts.connect()?;
            client::status(&mut c, opts.json, &mut std::io::stdout())?;
        }
        Cmd::Commission { axis, what } => {
            let (request, opts) = match what {
                CommissionWhat::Commutation {
                    current,
                    client: opts,
                } => (
                    Line::Commission {
                        axis,
                        procedure: CommissionKind::Commutation,
                        from: None,
                        to: None,
                        cycles: None,
                        speed: None,
                        current,
                    },
                    opts,
                ),
                CommissionWhat::Reversing {
                    from,
                    to,
                    cycles,
                    speed,
                    client: opts,
                } => (
                    Line::Commission {
                        axis,
                        procedure: CommissionKind::Reversing,
                        from: Some(from),
                        to: Some(to),
                        cycles: Some(cycles),
                        speed,
                        current: None,
                    },
                    opts,
                ),
            };
            // Ctrl-C stops the axis (and with it the procedure) instead of leaving it
            // running unattended.
            // SAFETY: the handler only stores to an atomic (async-signal-safe).
            unsafe {
                nix::sys::signal::signal(
                    nix::sys::signal::Signal::SIGINT,
                    nix::sys::signal::SigHandler::Handler(on_sigint),
                )
            }
            .context("installing the Ctrl-C handler")?;
            let mut c = opts.connect()?;
            client::commission(
                &mut c,
                &request,
                &INTERRUPTED,
                opts.json,
                &mut std::io::stdout(),
            )?;
        }
        Cmd::Axis(command) => AxisCommand::of(command)
            .map_err(anyhow::Error::msg)?
            .send()?,
        Cmd::Sdo { op } => {
            let (target, object, value, ty, timeout, opts, file) = match op {
                SdoOp::Upload {
                    target,
                    object,
                    ty,
                    out,
                    timeout,
                    client,
                } => (
                    target,
                    object,
                    None,
                    ty,
                    timeout,
                    client,
                    out.map(sdo_cli::File::Out),
                ),
                SdoOp::Download {
                    target,
                    object,
                    value,
                    ty,
                    file,
                    timeout,
                    client,
                } => (
                    target,
                    object,
                    value,
                    ty,
                    timeout,
                    client,
                    file.map(sdo_cli::File::In),
                ),
            };
            anyhow::ensure!(
                timeout.is_none_or(|t| (0.001..=60.0).contains(&t)),
                "--timeout must be 0.001 to 60 s"
            );
            // What was typed is checked before the service is asked.
            let (_, _) = sdo_cli::parse_address(&object)?;
            if let (Some(t), Some(v)) = (ty, &value) {
                sdo_cli::encode(t, v)?;
            }
            let mut c = opts.connect()?;
            sdo_cli::run(
                &mut c,
                &sdo_cli::Transfer {
                    target: target.target(),
                    address: &object,
                    value: value.as_deref(),
                    ty,
                    timeout_s: timeout,
                    file,
                },
                opts.json,
                &mut std::io::stdout(),
            )?;
        }
        Cmd::Cam { op } => cam_command(op)?,
        Cmd::Group { op } => op.command().map_err(anyhow::Error::msg)?.send()?,
        Cmd::Dcf { config, axis, out } => {
            println!("{}", gantry_cli::dcf::run(&config, &axis, &out)?);
        }
        Cmd::Trace {
            axes,
            xy,
            seconds,
            out,
            client: opts,
        } => {
            let mut c = opts.connect()?;
            let (axes, xy) = match xy {
                Some(pair) => (pair, true),
                None => (axes, false),
            };
            client::trace(&mut c, &axes, seconds, &out, xy, &mut std::io::stdout())?;
        }
        Cmd::RtCheck {
            config,
            cycle_us,
            seconds,
            can,
        } => {
            anyhow::ensure!(
                seconds.is_finite() && seconds > 0.0 && seconds <= 3600.0,
                "--seconds {seconds} must be above 0 and at most 3600"
            );
            let config = config
                .map(|c| gantry::config::Config::load(&c))
                .transpose()?;
            let rt = config.as_ref().map(|c| c.rt).unwrap_or_default();
            let interface = config.as_ref().and_then(|c| c.bus.interface.clone());
            let cycle = cycle_us
                .or(config.as_ref().map(|c| c.bus.cycle_us))
                .unwrap_or(1000);
            anyhow::ensure!(
                (50..=100_000).contains(&cycle),
                "--cycle-us {cycle} must be 50 to 100000"
            );
            if let Some(drives) = can {
                anyhow::ensure!(
                    (1..=127).contains(&drives),
                    "--can {drives}: a CANopen network has nodes 1 to 127"
                );
            }
            let mut stdout = std::io::stdout();
            match can {
                Some(drives) => {
                    gantry_cli::rt_check::write_findings(&rt, None, &mut stdout)?;
                    gantry_cli::rt_check::run_can(&rt, drives, cycle, seconds, &mut stdout)?;
                }
                None => gantry_cli::rt_check::run(
                    &rt,
                    interface.as_deref(),
                    cycle,
                    seconds,
                    &mut stdout,
                )?,
            }
        }
        Cmd::Scan {
            interface,
            json,
            pcap,
        } => {
            let rows = scan::scan(&interface, pcap.as_deref())?;
            let mut stdout = std::io::stdout();
            if json {
                serde_json::to_writer_pretty(&mut stdout, &rows)?;
                writeln!(stdout)?;
            } else {
                scan::print_table(&rows, &mut stdout)?;
            }
        }
        Cmd::Profile {
            from_pos,
            from_vel,
            from_acc,
            to_pos,
            vmax,
            amax,
            dmax,
            jmax,
            ramp,
            batch,
        } => {
            if batch {
                let stdin = std::io::stdin();
                profile::batch(stdin.lock(), std::io::stdout().lock()).context("batch I/O")?;
                return Ok(());
            }
            let amax = amax.context("--amax is required")?;
            let req = Request {
                from_pos,
                from_vel,
                from_acc,
                to_pos: to_pos.context("--to-pos is required")?,
                vmax: vmax.context("--vmax is required")?,
                amax,
                dmax: dmax.unwrap_or(amax),
                jmax,
                ramp,
            };
            let answer = profile::answer(&req, true).context("gantry profile")?;
            println!("{}", serde_json::to_string_pretty(&answer)?);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry::service::protocol;

    /// What the command line `args` sends, as the service reads it back off the wire.
    fn sent(args: &[&str]) -> (Line, bool) {
        let cli = Cli::try_parse_from(std::iter::once("gantry").chain(args.iter().copied()))
            .unwrap_or_else(|e| panic!("{args:?}: {e}"));
        let command = match cli.command {
            Cmd::Axis(cmd) => AxisCommand::of(cmd).unwrap_or_else(|e| panic!("{args:?}: {e}")),
            Cmd::Cam { op } => {
                cam_axis_command(op).unwrap_or_else(|| panic!("{args:?}: a table command"))
            }
            Cmd::Group { op } => op.command().unwrap_or_else(|e| panic!("{args:?}: {e}")),
            _ => panic!("{args:?} is not a one-axis command"),
        };
        let line = command.request.to_line().unwrap();
        let parsed = protocol::parse(&line).unwrap_or_else(|e| panic!("{line}: {e}"));
        assert_eq!(parsed, command.request, "{line}");
        (parsed, command.no_wait)
    }

    #[test]
    fn every_axis_command_reaches_the_service_as_typed() {
        let x = || "x".to_string();
        for (args, request, no_wait) in [
            (&["enable", "x"][..], Line::Enable { axis: x() }, false),
            (&["disable", "x"], Line::Disable { axis: x() }, false),
            (&["halt", "x"], Line::Halt { axis: x() }, false),
            (&["stop", "x"], Line::Stop { axis: x() }, false),
            (&["release", "x"], Line::Release { axis: x() }, false),
            (&["reset", "x"], Line::Reset { axis: x() }, false),
            (
                &["set-position", "x", "--position", "-2.5"],
                Line::SetPosition {
                    axis: x(),
                    position: -2.5,
                },
                false,
            ),
            (
                &["move", "x", "--to", "20"],
                Line::Move {
                    axis: x(),
                    to: 20.0,
                    mode: MoveMode::Absolute,
                    speed: None,
                    acceleration: None,
                    deceleration: None,
                    jerk: None,
                    buffer: BufferMode::Aborting,
                },
                false,
            ),
            (
                &[
                    "move",
                    "x",
                    "--to",
                    "-5",
                    "--mode",
                    "relative",
                    "--speed",
                    "100",
                    "--acceleration",
                    "1000",
                    "--deceleration",
                    "800",
                    "--jerk",
                    "20000",
                    "--buffer",
                    "blending-next",
                    "--no-wait",
                ],
                Line::Move {
                    axis: x(),
                    to: -5.0,
                    mode: MoveMode::Relative,
                    speed: Some(100.0),
                    acceleration: Some(1000.0),
                    deceleration: Some(800.0),
                    jerk: Some(20000.0),
                    buffer: BufferMode::BlendingNext,
                },
                true,
            ),
            (
                &[
                    "move", "x", "--to", "350", "--mode", "negative", "--buffer", "buffered",
                ],
                Line::Move {
                    axis: x(),
                    to: 350.0,
                    mode: MoveMode::Negative,
                    speed: None,
                    acceleration: None,
                    deceleration: None,
                    jerk: None,
                    buffer: BufferMode::Buffered,
                },
                false,
            ),
            (
                &["jog", "x", "--direction", "-", "--speed", "20"],
                Line::Jog {
                    axis: x(),
                    direction: JogDirection::Negative,
                    speed: 20.0,
                    master: None,
                    lock: None,
                    lock_position: None,
                },
                true,
            ),
            (
                &["jog", "x", "--direction", "positive", "--speed", "5"],
                Line::Jog {
                    axis: x(),
                    direction: JogDirection::Positive,
                    speed: 5.0,
                    master: None,
                    lock: None,
                    lock_position: None,
                },
                true,
            ),
            (
                &[
                    "jog",
                    "x",
                    "--direction",
                    "+",
                    "--speed",
                    "0.5",
                    "--master",
                    "m",
                    "--lock",
                    "position-forward",
                    "--lock-position",
                    "-90",
                ],
                Line::Jog {
                    axis: x(),
                    direction: JogDirection::Positive,
                    speed: 0.5,
                    master: Some("m".into()),
                    lock: Some(LockDirection::PositionForward),
                    lock_position: Some(-90.0),
                },
                true,
            ),
            (
                &["gear", "x", "--master", "m", "--ratio", "-3:2", "--actual"],
                Line::Gear {
                    axis: x(),
                    master: "m".into(),
                    numerator: -3,
                    denominator: 2,
                    source: Some(MasterSource::Actual),
                    acceleration: None,
                    deceleration: None,
                    jerk: None,
                    master_sync_position: None,
                    slave_sync_position: None,
                    master_start_distance: None,
                },
                true,
            ),
            (
                &[
                    "gear",
                    "x",
                    "--master",
                    "m",
                    "--ratio",
                    "2",
                    "--sync",
                    "90:-10",
                    "--start-distance",
                    "45",
                    "--acceleration",
                    "100",
                ],
                Line::Gear {
                    axis: x(),
                    master: "m".into(),
                    numerator: 2,
                    denominator: 1,
                    source: None,
                    acceleration: Some(100.0),
                    deceleration: None,
                    jerk: None,
                    master_sync_position: Some(90.0),
                    slave_sync_position: Some(-10.0),
                    master_start_distance: Some(45.0),
                },
                true,
            ),
            (&["gear", "x", "--out"], Line::GearOut { axis: x() }, true),
            (
                &[
                    "cam",
                    "in",
                    "x",
                    "--master",
                    "m",
                    "--table",
                    "knife",
                    "--once",
                    "--relative",
                    "--slave-offset",
                    "-5",
                    "--master-scaling",
                    "0.5",
                ],
                Line::Cam {
                    axis: x(),
                    master: "m".into(),
                    table: "knife".into(),
                    periodic: Some(false),
                    start: Some(CamStartMode::Relative),
                    source: None,
                    master_offset: None,
                    slave_offset: Some(-5.0),
                    master_scaling: Some(0.5),
                    slave_scaling: None,
                    acceleration: None,
                    deceleration: None,
                    jerk: None,
                },
                true,
            ),
            (&["cam", "out", "x"], Line::CamOut { axis: x() }, true),
            (
                &["group", "enable", "xy"],
                Line::Group {
                    group: "xy".into(),
                    op: GroupOp::Enable,
                },
                false,
            ),
            (
                &["group", "home", "xy"],
                Line::Group {
                    group: "xy".into(),
                    op: GroupOp::Home,
                },
                false,
            ),
            (
                &["group", "halt", "xy"],
                Line::Group {
                    group: "xy".into(),
                    op: GroupOp::Halt,
                },
                false,
            ),
            (
                &[
                    "group",
                    "line",
                    "xy",
                    "--to",
                    "10,-20.5",
                    "--velocity",
                    "50",
                    "--buffered",
                ],
                Line::MoveLinear {
                    group: "xy".into(),
                    to: vec![10.0, -20.5],
                    velocity: 50.0,
                    acceleration: None,
                    deceleration: None,
                    jerk: None,
                    relative: false,
                    buffer: BufferMode::Buffered,
                    transition: TransitionMode::None,
                    corner_deviation: None,
                },
                true,
            ),
            (
                &[
                    "group",
                    "line",
                    "xy",
                    "--to",
                    "10,-20.5",
                    "--velocity",
                    "50",
                    "--buffer",
                    "blending-next",
                    "--transition",
                    "corner-superimposed",
                    "--corner-deviation",
                    "0.5",
                ],
                Line::MoveLinear {
                    group: "xy".into(),
                    to: vec![10.0, -20.5],
                    velocity: 50.0,
                    acceleration: None,
                    deceleration: None,
                    jerk: None,
                    relative: false,
                    buffer: BufferMode::BlendingNext,
                    transition: TransitionMode::CornerSuperimposed,
                    corner_deviation: Some(0.5),
                },
                true,
            ),
            (
                &[
                    "group",
                    "arc",
                    "xy",
                    "--end",
                    "40,50",
                    "--radius",
                    "-30",
                    "--cw",
                    "--axes",
                    "1,0",
                    "--velocity",
                    "40",
                    "--relative",
                ],
                Line::MoveCircular {
                    group: "xy".into(),
                    mode: CircularMode::Radius,
                    aux: [-30.0, 0.0],
                    end: [40.0, 50.0],
                    direction: CircularDirection::Cw,
                    axes: Some([1, 0]),
                    velocity: 40.0,
                    acceleration: None,
                    deceleration: None,
                    jerk: None,
                    relative: true,
                    buffer: BufferMode::Aborting,
                    transition: TransitionMode::None,
                    corner_deviation: None,
                },
                false,
            ),
            (
                &[
                    "home",
                    "x",
                    "--drive",
                    "--method",
                    "19",
                    "--speed-switch",
                    "20",
                    "--home-offset",
                    "-1.5",
                    "--timeout",
                    "5",
                ],
                Line::DriveHome {
                    axis: x(),
                    params: DriveHomeParams {
                        method: Some(19),
                        speed_switch: Some(20.0),
                        home_offset: Some(-1.5),
                        timeout_s: Some(5.0),
                        ..DriveHomeParams::default()
                    },
                },
                false,
            ),
            (
                &["home", "x"],
                Line::Home {
                    axis: x(),
                    params: None,
                    step_switch: None,
                },
                false,
            ),
            (
                &["home", "x", "--move-home"],
                Line::Home {
                    axis: x(),
                    params: Some(HomeParams::default()),
                    step_switch: None,
                },
                false,
            ),
            (
                &["home", "x", "--direction", "-", "--jerk", "5000"],
                Line::Home {
                    axis: x(),
                    params: Some(HomeParams {
                        direction: Some(JogDirection::Negative),
                        jerk: Some(5000.0),
                        ..HomeParams::default()
                    }),
                    step_switch: None,
                },
                false,
            ),
            (
                &["home", "x", "--step-to-switch"],
                Line::Home {
                    axis: x(),
                    params: None,
                    step_switch: Some(StepSwitchParams::default()),
                },
                false,
            ),
            (
                &[
                    "home",
                    "x",
                    "--step-to-switch",
                    "--direction",
                    "switch-negative",
                    "--switch-mode",
                    "falling-edge-inverse",
                    "--velocity",
                    "20",
                    "--acceleration",
                    "300",
                    "--deceleration",
                    "40",
                    "--jerk",
                    "6000",
                    "--set-position",
                    "-12.5",
                    "--distance-limit",
                    "150",
                ],
                Line::Home {
                    axis: x(),
                    params: None,
                    step_switch: Some(StepSwitchParams {
                        direction: Some(StepDirection::SwitchNegative),
                        switch_mode: Some(StepSwitchMode::FallingEdgeInverse),
                        velocity: Some(20.0),
                        acceleration: Some(300.0),
                        deceleration: Some(40.0),
                        jerk: Some(6000.0),
                        set_position: Some(-12.5),
                        distance_limit: Some(150.0),
                    }),
                },
                false,
            ),
            (
                &["home", "x", "--drive", "--skip", "--no-wait"],
                Line::DriveHome {
                    axis: x(),
                    params: DriveHomeParams {
                        skip: Some(true),
                        ..DriveHomeParams::default()
                    },
                },
                true,
            ),
        ] {
            assert_eq!(sent(args), (request, no_wait), "{args:?}");
        }
    }

    #[test]
    fn drive_homing_refuses_movehome_options_by_name() {
        let cli = Cli::try_parse_from(["gantry", "home", "x", "--drive", "--jerk", "5"]).unwrap();
        let Cmd::Axis(cmd) = cli.command else {
            panic!("a one-axis command");
        };
        let e = AxisCommand::of(cmd).err().unwrap();
        assert_eq!(
            e,
            "--jerk is a MoveHome option; the drive homes by its method (--method)"
        );
    }

    #[test]
    fn each_homing_run_refuses_the_options_of_the_others_by_name() {
        for (args, says) in [
            (
                &["home", "x", "--switch-mode", "on"][..],
                "--switch-mode is a step-to-switch option (--step-to-switch)",
            ),
            (
                &["home", "x", "--velocity", "5"],
                "--velocity is a step-to-switch option (--step-to-switch)",
            ),
            (
                &["home", "x", "--step-to-switch", "--mode", "edge"],
                "--mode is a MoveHome option, not one of step-to-switch's",
            ),
            (
                &["home", "x", "--step-to-switch", "--speed-switch", "5"],
                "--speed-switch is a MoveHome option; step-to-switch searches at --velocity",
            ),
            (
                &["home", "x", "--step-to-switch", "--method", "19"],
                "--method is a drive homing option (--drive)",
            ),
            (
                &["home", "x", "--method", "19"],
                "--method is a drive homing option (--drive)",
            ),
            (
                &["home", "x", "--drive", "--set-position", "1"],
                "--set-position is a step-to-switch option; the drive homes by its method",
            ),
            (
                &["home", "x", "--step-to-switch", "--direction", "up"],
                r#"--direction: direction "up" is not one of "positive", "negative", "switch-positive", "switch-negative""#,
            ),
            (
                &["home", "x", "--direction", "switch-positive"],
                r#"--direction: direction "switch-positive" is not one of "+", "-", "positive", "negative" (MoveHome; with --step-to-switch also switch-positive, switch-negative)"#,
            ),
        ] {
            let cli = Cli::try_parse_from(std::iter::once("gantry").chain(args.iter().copied()))
                .unwrap_or_else(|e| panic!("{args:?}: {e}"));
            let Cmd::Axis(cmd) = cli.command else {
                panic!("a one-axis command");
            };
            let e = AxisCommand::of(cmd)
                .err()
                .unwrap_or_else(|| panic!("{args:?}"));
            assert!(e.contains(says), "{args:?}: {e}");
        }
        // Two homing runs at once: clap refuses, naming both.
        for args in [
            &["home", "x", "--step-to-switch", "--drive"][..],
            &["home", "x", "--move-home", "--step-to-switch"],
            &["home", "x", "--move-home", "--drive"],
        ] {
            let e = Cli::try_parse_from(std::iter::once("gantry").chain(args.iter().copied()))
                .unwrap_err()
                .to_string();
            assert!(e.contains("cannot be used with"), "{args:?}: {e}");
        }
        // A wrong switch mode: clap names the option and the words.
        let e = Cli::try_parse_from([
            "gantry",
            "home",
            "x",
            "--step-to-switch",
            "--switch-mode",
            "edge",
        ])
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("'--switch-mode <SWITCH_MODE>'")
                && e.contains(r#"switch_mode "edge" is not one of "on", "off""#),
            "{e}"
        );
    }

    #[test]
    fn a_group_move_takes_buffered_or_a_buffer_mode_not_both() {
        let e = Cli::try_parse_from([
            "gantry",
            "group",
            "line",
            "xy",
            "--to",
            "1,2",
            "--velocity",
            "5",
            "--buffered",
            "--buffer",
            "blending-next",
        ])
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("'--buffered' cannot be used with '--buffer <BUFFER>'"),
            "{e}"
        );
    }

    #[test]
    fn a_wrong_word_on_the_command_line_names_the_option_and_the_word() {
        for (args, option, says) in [
            (
                &["move", "x", "--to", "1", "--mode", "sideways"][..],
                "'--mode <MODE>'",
                r#"mode "sideways" is not one of "absolute", "relative""#,
            ),
            (
                &["move", "x", "--to", "1", "--buffer", "soon"],
                "'--buffer <BUFFER>'",
                r#"buffer "soon" is not one of "aborting""#,
            ),
            (
                &["jog", "x", "--direction", "up", "--speed", "1"],
                "'--direction <DIRECTION>'",
                r#"direction "up" is not one of "+", "-""#,
            ),
            (
                &[
                    "group",
                    "line",
                    "xy",
                    "--to",
                    "1,2",
                    "--velocity",
                    "5",
                    "--buffer",
                    "blended",
                ],
                "'--buffer <BUFFER>'",
                r#"buffer "blended" is not one of "aborting", "buffered", "blending-low""#,
            ),
            (
                &[
                    "group",
                    "arc",
                    "xy",
                    "--end",
                    "1,2",
                    "--center",
                    "0,1",
                    "--velocity",
                    "5",
                    "--transition",
                    "rounded",
                ],
                "'--transition <TRANSITION>'",
                r#"transition "rounded" is not one of "none", "corner-superimposed""#,
            ),
        ] {
            let e = Cli::try_parse_from(std::iter::once("gantry").chain(args.iter().copied()))
                .unwrap_err()
                .to_string();
            assert!(e.contains(option), "{args:?}: {e}");
            assert!(e.contains(says), "{args:?}: {e}");
        }
    }
}
