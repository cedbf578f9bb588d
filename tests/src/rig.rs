//! gantry's engine over the in-process simulator, driven from one test thread: what `gantry
//! run` runs (bring-up from a configuration, [`Engine`], requests through a
//! [`Controller`]), minus the real-time thread, in lockstep: the simulated network's time
//! moves one cycle time per cycle (in phase with SYNC0, as [`Engine::run`] holds it) and
//! each frame passes the chain in the test thread, so whatever the host does, the drives
//! see a master exactly on time. The faults a test sees are the ones it injected.

use std::sync::{Arc, Mutex};

use gantry::config::Config;
use gantry::ethercat::bus::EthercatBus;
use gantry::runtime::bus::CycleBus;
use gantry::runtime::clock::{Clock, StepClock, Wake};
use gantry::runtime::controller::{CommandHandle, Controller};
use gantry::runtime::cycle::Cycle;
use gantry::runtime::engine::{Engine, LateReply};
use gantry::runtime::protocol::Snapshot;
use gantry_cli::simulator::{self, SimLink};
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_sim::chain::SlaveChain;
use gantry_sim::plant::servo::ServoDrive;
use gantry_sim::plant::DeviceModel;

/// Engine, controller and the simulated chain.
pub struct Rig {
    /// The engine (stepped by [`Rig::cycle`]).
    pub engine: Engine<EthercatBus>,
    /// The application's side.
    pub ctl: Controller,
    /// The simulated chain, for injecting faults.
    pub chain: Arc<Mutex<SlaveChain>>,
    clock: StepClock<Box<dyn FnMut(u64)>>,
}

impl Rig {
    /// Brings the bus of `config` (an in-process simulator) up and starts the engine.
    pub fn new(config: &Config) -> Self {
        Self::logged(config, &mut std::io::sink())
    }

    /// [`Rig::new`], writing the bring-up's steps to `log`.
    pub fn logged(config: &Config, log: &mut (dyn std::io::Write + Send)) -> Self {
        let sim = config.bus.simulator.as_deref().expect("[bus] simulator");
        let (link, simulated) = simulator::open(sim, SimLink::Lockstep)
            .unwrap_or_else(|e| panic!("the simulator: {}", gantry::error_chain::Chain(&e)));
        let bus = EthercatBus::bring_up_on(config, link, log)
            .unwrap_or_else(|e| panic!("bus up: {}", gantry::error_chain::Chain(&e)));
        let cycle = Cycle::from_config(config, &bus)
            .unwrap_or_else(|e| panic!("the cycle: {}", gantry::error_chain::Chain(&e)));
        assert!(simulated.step_by_hand(), "the chain in lockstep");
        let chain = simulated.chain();
        let period_ns = u64::from(config.bus.cycle_us) * 1000;
        let (mut engine, ends) = Engine::new(bus, cycle, config.rt.overrun_limit, 1024);
        // Every reply is in before the exchange looks for it: no wait ever runs out.
        engine.set_late_reply(LateReply::WAIT);
        let names = config.axes.iter().map(|a| a.name.clone()).collect();
        let start_ns = chain.lock().expect("the chain").now_ns();
        let stepped = chain.clone();
        let advance: Box<dyn FnMut(u64)> = Box::new(move |to_ns| {
            stepped
                .lock()
                .expect("the chain")
                .run_until(to_ns, period_ns)
        });
        Self {
            engine,
            ctl: Controller::new(ends, names),
            chain,
            clock: StepClock::new(period_ns, start_ns, advance),
        }
    }

    /// One cycle, on time (a test injects the overruns it means with [`Rig::wake`] and
    /// [`Rig::step`]).
    pub fn cycle(&mut self) {
        assert!(self.engine.cycle(&mut self.clock), "the engine ended");
    }

    /// One cycle with this wake-up (a test may mark it overrun).
    pub fn step(&mut self, wake: Wake) {
        assert!(self.engine.step(wake), "the engine ended");
        self.clock.shift(self.engine.phase_correction_ns());
    }

    /// The next wake-up, for a test to alter before [`Rig::step`]: the network's time
    /// moves one cycle time on.
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
        let status = self.command(axis, Command::Power(PowerCommand::Enable));
        assert_eq!(
            status,
            CommandStatus::Done,
            "enable axis {axis}: bus fault {:?}, drive {:?}",
            self.bus_fault(axis),
            self.snapshot().drives.get(axis)
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

    /// The status of `handle` as of the last cycle (the snapshot, which
    /// [`CommandHandle::status`] reads, has it only every few cycles): for a test that
    /// asserts the cycle a command ended in.
    pub fn status_now(&self, handle: &CommandHandle) -> Option<CommandStatus> {
        self.engine.command_status(handle.id())
    }

    /// `f` of the simulated servo at chain position `slave` (the simulator's truth: what
    /// reached the drive, where its load is).
    pub fn servo<R>(&self, slave: usize, f: impl FnOnce(&ServoDrive) -> R) -> R {
        let chain = self.chain.lock().expect("the chain");
        match chain.slaves()[slave].device() {
            DeviceModel::Servo(s) => f(s),
            other => panic!("slave {slave} is {other:?}"),
        }
    }

    /// Why the bus stopped `axis`' drive, as `gantry status` shows it.
    pub fn bus_fault(&self, axis: usize) -> Option<String> {
        let drive = self.engine.cycle.drive_of(axis);
        self.engine.bus.fault(drive).map(|f| f.to_string())
    }
}
