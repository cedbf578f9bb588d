//! The script runner both demos share: the script's steps — axis and axis-group commands —
//! issued through the [`Controller`](gantry::runtime::controller::Controller) as an
//! application would, each when its [`Wait`] is over; every cycle checked (an axis in
//! ErrorStop, a bus fault, a failed step stop the demo with what and why); the status
//! table drawn live at the pace `--speed` asks; the engine's own shutdown at the end. What
//! each demo records of a cycle (its trace) is its [`Watch`].

use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

use gantry::axis_fault::describe_fault;
use gantry::config::Config;
use gantry::runtime::bus::CycleBus;
use gantry::runtime::controller::CommandHandle;
use gantry::runtime::protocol::Snapshot;
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;

use super::lockstep::Lockstep;
use super::{DemoError, Order, Step, Wait};
use crate::status_table::{self, Live, Row};

/// Cycles between two snapshots of the engine (it publishes every 10).
pub const SNAPSHOT_CYCLES: u64 = 10;

/// The engine's own shutdown (quick stop, disable) takes at most 5000 cycles.
const SHUTDOWN_LIMIT_CYCLES: u64 = 6_000;

/// What a demo records of the cycles the runner runs.
pub trait Watch<B: CycleBus> {
    /// After each cycle before the shutdown.
    fn cycled(&mut self, net: &Lockstep<B>) -> Result<(), DemoError>;
    /// After the script's last cycle, before the final status table.
    fn settled(&mut self, net: &Lockstep<B>);
    /// After each cycle of the shutdown; `ended`: the engine has ended (the last one).
    fn shutdown_cycled(&mut self, net: &Lockstep<B>, ended: bool) -> Result<(), DemoError>;
}

/// A step issued, and its handle.
struct Issued {
    step: Step,
    handle: CommandHandle,
}

/// How long a script may run and how it ends.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// The cycle count past which a wait fails the demo.
    pub cycles: u64,
    /// Cycles run after the last move, so the trace shows the axes at rest.
    pub tail: u64,
}

/// What the script keeps while it runs.
pub struct Runner {
    names: Vec<String>,
    /// Each axis' type, for the table.
    types: Vec<&'static str>,
    speed: f64,
    started: Instant,
    live: Live,
    /// Every step issued, in order.
    issued: Vec<Issued>,
    /// Per axis, the index in `issued` of its last step.
    last: Vec<Option<usize>>,
    /// The axis groups' names (`[[group]]` order).
    groups: Vec<String>,
    /// Per group, the index in `issued` of its last step.
    last_group: Vec<Option<usize>>,
    frame_cycles: u64,
    /// Whether the drives report an error code (0x603F) to name when an axis stops.
    error_codes: bool,
}

impl Runner {
    /// For the axes of `config`, a status table every `frame_cycles` (a multiple of
    /// [`SNAPSHOT_CYCLES`]) at `speed` simulated seconds per second (0: no pause).
    pub fn new(config: &Config, speed: f64, frame_cycles: u64, error_codes: bool) -> Self {
        Self {
            names: config.axes.iter().map(|a| a.name.clone()).collect(),
            types: config.axes.iter().map(|a| a.axis_type.name()).collect(),
            speed,
            started: Instant::now(),
            live: Live::new(std::io::stdout().is_terminal()),
            issued: Vec::new(),
            last: vec![None; config.axes.len()],
            groups: config.groups.iter().map(|g| g.name.clone()).collect(),
            last_group: vec![None; config.groups.len()],
            frame_cycles,
            error_codes,
        }
    }

    /// One cycle and what the demo watches: its record, the status table, and every
    /// fault or failed step (which fails the demo at once).
    pub fn cycle<B: CycleBus>(
        &mut self,
        net: &mut Lockstep<B>,
        watch: &mut impl Watch<B>,
        out: &mut dyn Write,
    ) -> Result<(), DemoError> {
        if !net.cycle() {
            return Err(DemoError::Fault("the engine ended".into()));
        }
        watch.cycled(net)?;
        let n = net.cycles();
        if n % SNAPSHOT_CYCLES == 0 {
            let snap = net.ctl.snapshot();
            self.check(&snap)?;
            if n % self.frame_cycles == 0 {
                self.frame(&snap, out);
            }
        }
        Ok(())
    }

    /// Fails on what an application must not run past (see [`check`]).
    pub fn check(&self, snap: &Snapshot) -> Result<(), DemoError> {
        check(snap, &self.names, &self.issued, self.error_codes)
    }

    /// The status table, and the pace (`--speed`).
    fn frame(&mut self, snap: &Snapshot, out: &mut dyn Write) {
        let rows: Vec<Row> = self
            .names
            .iter()
            .enumerate()
            .map(|(i, name)| {
                let status = snap.axes.get(i).copied().unwrap_or_default();
                let command = self
                    .last
                    .get(i)
                    .copied()
                    .flatten()
                    .and_then(|k| self.issued.get(k))
                    .and_then(|k| snap.status_of(k.handle.id()));
                Row {
                    axis: name.clone(),
                    axis_type: self.types.get(i).copied().unwrap_or("real"),
                    status,
                    command: command.map(|c| c.name().to_string()).unwrap_or_default(),
                    error: status.error.map(|e| describe_fault(&e)).unwrap_or_default(),
                }
            })
            .collect();
        let frame = status_table::render(snap.time_s, &rows);
        let _ = out.write_all(self.live.frame(&frame).as_bytes());
        let _ = out.flush();
        if self.speed > 0.0 {
            let due = Duration::from_secs_f64(snap.time_s / self.speed);
            if let Some(wait) = due.checked_sub(self.started.elapsed()) {
                std::thread::sleep(wait);
            }
        }
    }

    /// Whether the command of step `label` is final.
    fn done(&self, label: &'static str) -> Result<bool, DemoError> {
        let issued = self
            .issued
            .iter()
            .rev()
            .find(|i| i.step.label == label)
            .ok_or(DemoError::Script(label))?;
        Ok(issued.handle.status().is_some_and(|s| s.is_final()))
    }

    /// `script` through the Controller, to its end, then the axes at rest a while, and
    /// where they ended.
    pub fn script<B: CycleBus>(
        &mut self,
        net: &mut Lockstep<B>,
        watch: &mut impl Watch<B>,
        script: Vec<Step>,
        limits: Limits,
        out: &mut dyn Write,
    ) -> Result<(), DemoError> {
        for step in script {
            let waited_from = net.time();
            // When the step waited for was first seen done.
            let mut done_at: Option<f64> = None;
            loop {
                let ready = match step.wait {
                    Wait::Now => true,
                    Wait::Seconds(s) => net.time() - waited_from >= s - 1e-9,
                    Wait::Done(label) => self.done(label)?,
                    Wait::DoneAll(labels) => {
                        let mut all = true;
                        for &label in labels {
                            all &= self.done(label)?;
                        }
                        all
                    }
                    Wait::DoneFor(label, s) => {
                        if done_at.is_none() && self.done(label)? {
                            done_at = Some(net.time());
                        }
                        done_at.is_some_and(|t| net.time() - t >= s - 1e-9)
                    }
                };
                if ready {
                    break;
                }
                if net.cycles() > limits.cycles {
                    return Err(DemoError::Timeout(step.label));
                }
                self.cycle(net, watch, out)?;
            }
            let (names, last) = match step.command {
                Order::Axis(_) => (&self.names, &mut self.last),
                Order::Group(_) => (&self.groups, &mut self.last_group),
            };
            let target = names
                .iter()
                .position(|n| n == step.axis)
                .ok_or(DemoError::Script(step.axis))?;
            if let Some(last) = last.get_mut(target) {
                *last = Some(self.issued.len());
            }
            let handle = match step.command {
                Order::Axis(command) => net.ctl.command(target, command),
                Order::Group(command) => net.ctl.group_command(target, command),
            }
            .map_err(|e| DemoError::Fault(format!("step {}: {e}", step.label)))?;
            if !step.says.is_empty() {
                let _ = writeln!(out, ">> {}", step.says);
            }
            self.issued.push(Issued { step, handle });
        }
        // The last moves to their end (in position), then the axes at rest a while.
        while self
            .last
            .iter()
            .chain(&self.last_group)
            .flatten()
            .filter_map(|&k| self.issued.get(k))
            .any(|i| !i.handle.status().is_some_and(|s| s.is_final()))
        {
            if net.cycles() > limits.cycles {
                return Err(DemoError::Timeout("final moves"));
            }
            self.cycle(net, watch, out)?;
        }
        for _ in 0..limits.tail {
            self.cycle(net, watch, out)?;
        }
        watch.settled(net);
        let snap = net.ctl.snapshot();
        self.check(&snap)?;
        self.frame(&snap, out);
        let _ = writeln!(out, ">> the axes at the end:");
        for (i, name) in self.names.iter().enumerate() {
            let (Some(a), Some(d)) = (snap.axes.get(i), snap.drives.get(i)) else {
                continue;
            };
            let _ = writeln!(
                out,
                "   {name}: {}, set {:.4}, actual {:.4}, {}",
                a.state.name(),
                a.set.p,
                a.actual_position,
                match self.types.get(i).copied() {
                    Some("real") | None => format!("drive {}", drive_state(d.state)),
                    Some(other) => format!("no drive ({other})"),
                }
            );
        }
        Ok(())
    }

    /// Quick stop and disable through the engine's own shutdown, as `gantry run` on
    /// SIGTERM; then `said`.
    pub fn shut_down<B: CycleBus>(
        &mut self,
        net: &mut Lockstep<B>,
        watch: &mut impl Watch<B>,
        said: &str,
        out: &mut dyn Write,
    ) -> Result<(), DemoError> {
        net.ctl
            .shutdown()
            .map_err(|e| DemoError::Fault(format!("shutdown: {e}")))?;
        for _ in 0..SHUTDOWN_LIMIT_CYCLES {
            let ended = !net.cycle();
            watch.shutdown_cycled(net, ended)?;
            if ended {
                let _ = writeln!(out, ">> {said}");
                return Ok(());
            }
        }
        Err(DemoError::Timeout("shutdown"))
    }
}

/// A drive's CiA-402 state as the demos name it.
pub fn drive_state(state: Option<gantry_drives::cia402::State>) -> &'static str {
    state.map_or("not reporting", gantry_drives::cia402::State::name)
}

/// Fails on what an application must not run past: a drive whose bus stopped it, an
/// axis in ErrorStop (with the drive's error code where `error_codes`), a step of the
/// script whose command failed.
fn check(
    snap: &Snapshot,
    names: &[String],
    issued: &[Issued],
    error_codes: bool,
) -> Result<(), DemoError> {
    for (i, name) in names.iter().enumerate() {
        let drive = snap.drives.get(i).copied().unwrap_or_default();
        if let Some(fault) = drive.bus_fault {
            return Err(DemoError::Fault(format!("axis {name}: bus fault: {fault}")));
        }
        if let Some(a) = snap.axes.get(i).filter(|a| a.state == AxisState::ErrorStop) {
            let why = a
                .error
                .map_or_else(|| "no reason given".into(), |e| describe_fault(&e));
            let code = if error_codes {
                let code = drive.error_code;
                format!(
                    ", error code {}",
                    code.map_or_else(|| "-".into(), |c| format!("0x{c:04X}"))
                )
            } else {
                String::new()
            };
            return Err(DemoError::Fault(format!(
                "axis {name} in ErrorStop: {why} (drive {}, statusword 0x{:04X}{code})",
                drive_state(drive.state),
                drive.statusword,
            )));
        }
    }
    for i in issued {
        if let Some(CommandStatus::Error(error)) = snap.status_of(i.handle.id()) {
            return Err(DemoError::Step {
                label: i.step.label,
                axis: i.step.axis,
                command: i.step.command.name(),
                error: Box::new(error),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_axis_in_error_stop_or_a_bus_fault_stops_the_demo_with_what_and_why() {
        use gantry::ethercat::health::BusFault;
        use gantry::runtime::bus::Unreachable;
        use gantry_kernel::axis::status::AxisFault;
        let names: Vec<String> = ["x", "y", "c"].map(String::from).into();
        let mut snap = Snapshot::sized(3);
        check(&snap, &names, &[], true).unwrap();
        snap.axes[2].state = AxisState::ErrorStop;
        snap.axes[2].error = Some(AxisFault::Drive { code: 0x8611 });
        snap.drives[2].state = Some(gantry_drives::cia402::State::Fault);
        snap.drives[2].statusword = 0x0218;
        snap.drives[2].error_code = Some(0x8611);
        let e = check(&snap, &names, &[], true).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("the demo stopped: axis c in ErrorStop: drive fault 0x8611: ")
                && e.to_string()
                    .ends_with("(drive Fault, statusword 0x0218, error code 0x8611)"),
            "{e}"
        );
        // Drives with no error code: the statusword ends the message.
        let e = check(&snap, &names, &[], false).unwrap_err();
        assert!(
            e.to_string().ends_with("(drive Fault, statusword 0x0218)"),
            "{e}"
        );
        snap.drives[0].bus_fault = Some(Unreachable::new(&BusFault::FramesLost {
            count: 3,
            limit: 3,
        }));
        let e = check(&snap, &names, &[], true).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the demo stopped: axis x: bus fault: EtherCAT: 3 frames lost in a row (limit 3)"
        );
    }
}
