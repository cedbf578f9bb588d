//! gantry's engine over the in-process simulator, driven from one test thread: what `gantry
//! run` runs (bring-up from a configuration, [`Engine`], requests through a
//! [`Controller`]), minus the real-time thread. The test thread is not real time, so a late
//! reply is this host's doing and the engine waits for it ([`LateReply::WAIT`]), and a late
//! start is no overrun ([`Rig::cycle`]): the faults a test sees are the ones it injected.

use std::sync::{Arc, Mutex};

use gantry::config::Config;
use gantry::ethercat::bus::EthercatBus;
use gantry::runtime::clock::{CycleClock, Wake};
use gantry::runtime::controller::{CommandHandle, Controller};
use gantry::runtime::engine::{Engine, LateReply};
use gantry::runtime::protocol::Snapshot;
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_sim::chain::SlaveChain;

/// Cycle time of the rig (ns).
pub const PERIOD_NS: u64 = 1_000_000;

/// Engine, controller and the simulated chain.
pub struct Rig {
    /// The engine (stepped by [`Rig::cycle`]).
    pub engine: Engine<EthercatBus>,
    /// The application's side.
    pub ctl: Controller,
    /// The simulated chain, for injecting faults.
    pub chain: Arc<Mutex<SlaveChain>>,
    clock: CycleClock,
}

impl Rig {
    /// Brings the bus of `config` (an in-process simulator) up and starts the engine.
    pub fn new(config: &Config) -> Self {
        let (bus, cycle, health) =
            EthercatBus::bring_up(config, &mut std::io::sink()).expect("bus up");
        let chain = bus.simulated_chain().expect("the in-process simulator");
        let (mut engine, ends) = Engine::new(bus, cycle, health, config.rt.overrun_limit, 1024);
        engine.set_late_reply(LateReply::WAIT);
        let names = config.axes.iter().map(|a| a.name.clone()).collect();
        Self {
            engine,
            ctl: Controller::new(ends, names),
            chain,
            clock: CycleClock::start(PERIOD_NS),
        }
    }

    /// One cycle at the next deadline. The test thread is not real time: a cycle that
    /// starts late is this host's doing, and is not counted as an overrun (which would
    /// stop every axis after `rt.overrun_limit` in a row on a busy host); a test injects
    /// the overruns it means with [`Rig::wake`] and [`Rig::step`].
    pub fn cycle(&mut self) {
        let mut wake = self.clock.wait();
        wake.overrun = false;
        self.step(wake);
    }

    /// One cycle with this wake-up (a test may mark it overrun).
    pub fn step(&mut self, wake: Wake) {
        assert!(self.engine.step(wake), "the engine ended");
    }

    /// The next wake-up, for a test to alter before [`Rig::step`].
    pub fn wake(&mut self) -> Wake {
        self.clock.wait()
    }

    /// `n` cycles.
    pub fn run(&mut self, n: usize) {
        for _ in 0..n {
            self.cycle();
        }
    }

    /// Cycles until `handle` is final (at most `max` cycles); its status.
    pub fn finish(&mut self, handle: &CommandHandle, max: usize) -> CommandStatus {
        for _ in 0..max {
            self.cycle();
            if let Some(s) = handle.status().filter(CommandStatus::is_final) {
                return s;
            }
        }
        panic!("not finished in {max} cycles: {:?}", handle.status());
    }

    /// Sends `command` to `axis` and cycles until it is final; its status.
    pub fn command(&mut self, axis: usize, command: Command) -> CommandStatus {
        let h = self.ctl.command(axis, command).expect("queued");
        self.finish(&h, 5000)
    }

    /// Enables `axis` and calls its position 0.
    pub fn enable_and_home(&mut self, axis: usize) {
        assert_eq!(
            self.command(axis, Command::Power(PowerCommand::Enable)),
            CommandStatus::Done
        );
        let home = Command::SetPosition {
            position: 0.0,
            relative: false,
        };
        assert_eq!(self.command(axis, home), CommandStatus::Done);
    }

    /// Starts an absolute move of `axis` to `to`.
    pub fn start_move(&mut self, axis: usize, to: f64) -> CommandHandle {
        let cmd = Command::MovePtp(MovePtp::new(PositioningMode::AbsNormal, to));
        self.ctl.command(axis, cmd).expect("queued")
    }

    /// The latest snapshot (published every 10 cycles).
    pub fn snapshot(&self) -> Snapshot {
        self.ctl.snapshot()
    }

    /// The state of `axis` as the kernel has it now.
    pub fn state(&self, axis: usize) -> AxisState {
        self.engine
            .cycle
            .kernel
            .axis_status(axis)
            .expect("axis")
            .state
    }

    /// Why the bus stopped `axis`' drive, as `gantry status` shows it.
    pub fn bus_fault(&self, axis: usize) -> Option<String> {
        self.engine.health.fault(axis).map(|f| f.to_string())
    }
}
