//! gantry's CANopen bus over simulated nodes in this process, driven from one test
//! thread, in lockstep: the in-memory CAN bus ([`gantry_sim::canopen::CanBus`]: arbitration
//! and the bit rate's frame timing) behind the master's [`gantry::canopen::CanLink`] ([`MemLink`]), and the
//! engine, the controller and a [`StepClock`] that moves the bus' time one cycle per cycle,
//! as [`crate::rig::Rig`] does for EtherCAT.
//!
//! Time: see [`gantry_cli::can_simulator`] (lockstep): during the bring-up the link runs
//! its own clock; once the engine runs ([`MemBus::stepped`]) the step clock moves it, and
//! an exchange receives what the bus delivered by the cycle's reply window.

use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Mutex, MutexGuard};

use gantry::canopen::bring_up::StartError;
use gantry::canopen::{CanLink, CanopenBus, Received};
use gantry::config::Config;
use gantry::runtime::bus::CycleBus;
use gantry::runtime::clock::StepClock;
use gantry::runtime::controller::{CommandHandle, Controller};
use gantry::runtime::cycle::Cycle;
use gantry::runtime::engine::Engine;
use gantry::runtime::protocol::Snapshot;
use gantry_drives::canopen::{CanFrame, NodeId};
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_sim::canopen::{CanNode, CanNodeConfig};

/// The in-memory bus and its link: the binary's in-process CANopen simulator, in lockstep.
pub use gantry_cli::can_simulator::{lock, MemBus, MemLink, SharedBus};

/// A CANopen configuration: one axis per node in `nodes` (5 mm ball screws on 2^17-count
/// motors, 200 mm/s), `pdo` layout, cycle `cycle_us`, 1 Mbit/s, on the in-memory bus.
pub fn can_config(nodes: &[u8], cycle_us: u32, pdo: &str) -> Config {
    can_config_with(nodes, cycle_us, pdo, "")
}

/// [`can_config`] with more `[bus]` lines.
pub fn can_config_with(nodes: &[u8], cycle_us: u32, pdo: &str, bus: &str) -> Config {
    can_config_axes(nodes, cycle_us, pdo, bus, "")
}

/// [`can_config_with`] with `axis` (keys and tables of `[[axis]]`, e.g.
/// `[axis.switches]`) after each axis.
pub fn can_config_axes(nodes: &[u8], cycle_us: u32, pdo: &str, bus: &str, axis: &str) -> Config {
    let text = can_config_text(nodes, cycle_us, pdo, bus, axis);
    Config::parse(&text, "can.toml").unwrap_or_else(|e| panic!("{e}"))
}

/// The text of [`can_config_axes`].
pub fn can_config_text(nodes: &[u8], cycle_us: u32, pdo: &str, bus: &str, axis: &str) -> String {
    let mut text = format!(
        "[bus]\nkind = \"canopen\"\ninterface = \"mem0\"\nbitrate = 1000000\n\
         cycle_us = {cycle_us}\n{bus}\n"
    );
    for (i, node) in nodes.iter().enumerate() {
        text += &format!(
            "[[axis]]\nname = \"a{i}\"\nnode = {node}\npdo = \"{pdo}\"\n\
             scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
             max = {{ speed = 200.0, acceleration = 2000.0, jerk = 20000.0 }}\n{axis}"
        );
    }
    text
}

/// Simulated servos with these node ids (heartbeat every 100 ms, as the configuration's
/// default asks for anyway).
pub fn servos(ids: &[u8]) -> Vec<CanNode> {
    servos_with_pdos(ids, gantry_sim::canopen::pdo::DEFAULT_PDO_COUNT)
}

/// [`servos`] with `pdo_count` PDOs each way (the chain's `pdo_count`).
pub fn servos_with_pdos(ids: &[u8], pdo_count: u8) -> Vec<CanNode> {
    ids.iter()
        .map(|&n| {
            CanNode::new(CanNodeConfig {
                pdo_count,
                ..CanNodeConfig::servo(NodeId::new(n).expect("node id"))
            })
            .expect("a simulated servo")
        })
        .collect()
}

/// Engine, controller and the simulated CAN bus.
pub struct CanRig {
    /// The engine (stepped by [`CanRig::cycle`]).
    pub engine: Engine<CanopenBus>,
    /// The application's side.
    pub ctl: Controller,
    /// The simulated bus, for the test's eyes and faults.
    pub bus: SharedBus,
    clock: StepClock<Box<dyn FnMut(u64)>>,
    /// What the bring-up printed.
    pub log: String,
}

impl CanRig {
    /// Brings `config`'s bus up on `nodes` at 1 Mbit/s and starts the engine.
    pub fn new(config: &Config, nodes: Vec<CanNode>) -> Self {
        Self::try_new(config, nodes)
            .unwrap_or_else(|e| panic!("bus up: {}", gantry::error_chain::Chain(&e)))
    }

    /// [`CanRig::new`], or why the bus did not come up.
    pub fn try_new(config: &Config, nodes: Vec<CanNode>) -> Result<Self, StartError> {
        Self::on_bitrate(config, nodes, config.bus.bitrate)
    }

    /// [`CanRig::try_new`] on a bus that really runs at `bitrate` (whatever the
    /// configuration says; None: frames take no time).
    pub fn on_bitrate(
        config: &Config,
        nodes: Vec<CanNode>,
        bitrate: Option<u32>,
    ) -> Result<Self, StartError> {
        let (link, bus) = MemLink::new(nodes, bitrate);
        let mut log = Vec::new();
        let canopen = CanopenBus::bring_up_on(config, Box::new(link), &mut log)?;
        let cycle = Cycle::from_config(config, &canopen)
            .unwrap_or_else(|e| panic!("the cycle: {}", gantry::error_chain::Chain(&e)));
        let period_ns = u64::from(config.bus.cycle_us) * 1000;
        let (engine, ends) = Engine::new(canopen, cycle, config.rt.overrun_limit, 1024);
        let start_ns = {
            let mut b = lock(&bus);
            b.stepped(period_ns);
            b.now_ns()
        };
        let stepped = bus.clone();
        let advance: Box<dyn FnMut(u64)> = Box::new(move |to_ns| lock(&stepped).cycle_at(to_ns));
        let names = config.axes.iter().map(|a| a.name.clone()).collect();
        Ok(Self {
            engine,
            ctl: Controller::new(ends, names),
            bus,
            clock: StepClock::new(period_ns, start_ns, advance),
            log: String::from_utf8_lossy(&log).into_owned(),
        })
    }

    /// One cycle.
    pub fn cycle(&mut self) {
        assert!(self.engine.cycle(&mut self.clock), "the engine ended");
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
            if let Some(s) = self
                .engine
                .command_status(handle.id())
                .filter(CommandStatus::is_final)
            {
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
            "enable axis {axis}: bus fault {:?}",
            self.bus_fault(axis)
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

    /// Starts absolute moves of axes 0, 1, … to `targets`.
    pub fn start_moves(&mut self, targets: &[f64]) -> Vec<CommandHandle> {
        targets
            .iter()
            .enumerate()
            .map(|(axis, &to)| self.start_move(axis, to))
            .collect()
    }

    /// `index:sub` of `node` as its SDO server reads it, little-endian into a u32.
    pub fn read_u32(&self, node: u8, index: u16, sub: u8) -> u32 {
        let mut out = [0u8; 4];
        let n = self
            .sim()
            .node_mut(node)
            .read_object(index, sub, &mut out)
            .unwrap_or_else(|e| panic!("node {node} 0x{index:04X}:{sub}: {e}"));
        let mut b = [0u8; 4];
        b[..n].copy_from_slice(&out[..n]);
        u32::from_le_bytes(b)
    }

    /// The latest snapshot.
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

    /// Why the bus stopped `axis`' drive.
    pub fn bus_fault(&self, axis: usize) -> Option<String> {
        let drive = self.engine.cycle.drive_of(axis);
        self.engine.bus.fault(drive).map(|f| f.to_string())
    }

    /// The simulated bus, locked.
    pub fn sim(&self) -> MutexGuard<'_, MemBus> {
        lock(&self.bus)
    }

    /// Shuts down as `gantry run` does on SIGTERM: [`Controller::shutdown`], cycles until
    /// the engine ends (the drives disabled; at most `max` cycles), then the bus'
    /// shutdown ([`CanopenBus::shut_down`]) with the bus' time running on by the link's
    /// waits. Returns what the shutdown printed and the simulated bus.
    pub fn shut_down(mut self, max: usize) -> (String, SharedBus) {
        self.ctl.shutdown().expect("shutdown queued");
        let mut ended = false;
        for _ in 0..max {
            if !self.engine.cycle(&mut self.clock) {
                ended = true;
                break;
            }
        }
        assert!(ended, "the engine did not end in {max} cycles");
        lock(&self.bus).free_running();
        let mut out = Vec::new();
        let _ = self.engine.into_bus().shut_down(&mut out);
        (String::from_utf8_lossy(&out).into_owned(), self.bus)
    }
}

/// Frames [`Nodes`] holds for the master at most.
pub const QUEUE: usize = 4096;

/// Nodes behind a fixed queue, a lockstep bus that allocates nothing (no arbitration, no
/// bit timing: [`MemBus`] has those): a frame the master sends reaches every node at
/// once, what they answer waits in the queue for the master.
pub struct Nodes {
    /// The nodes.
    pub nodes: Vec<CanNode>,
    /// What they sent, for the master.
    pub queue: VecDeque<CanFrame>,
    /// The bus' clock (ns).
    pub clock_ns: u64,
    /// Moved by the engine's clock ([`Nodes::tick`]); before, by the link's waits.
    pub stepped: bool,
    /// Frames with this identifier do not reach the master.
    pub drop: Option<u16>,
    /// Frames lost to a full queue.
    pub overflow: u64,
}

impl Nodes {
    fn push(queue: &mut VecDeque<CanFrame>, overflow: &mut u64, drop: Option<u16>, f: &[CanFrame]) {
        for frame in f {
            if Some(frame.id()) == drop {
                continue;
            }
            if queue.len() < QUEUE {
                queue.push_back(*frame);
            } else {
                *overflow += 1;
            }
        }
    }

    /// `nodes` at time 0, the link's waits moving the time (bring-up).
    pub fn new(nodes: Vec<CanNode>) -> Self {
        Self {
            nodes,
            queue: VecDeque::with_capacity(QUEUE),
            clock_ns: 0,
            stepped: false,
            drop: None,
            overflow: 0,
        }
    }

    /// Lets the nodes' time pass to `to_ns`.
    pub fn tick(&mut self, to_ns: u64) {
        self.clock_ns = self.clock_ns.max(to_ns);
        for n in &mut self.nodes {
            let out = n.tick(self.clock_ns);
            Self::push(&mut self.queue, &mut self.overflow, self.drop, out);
        }
    }

    /// `frame` reaches every node now.
    pub fn deliver(&mut self, frame: &CanFrame) {
        for n in &mut self.nodes {
            let out = n.receive(frame, self.clock_ns);
            Self::push(&mut self.queue, &mut self.overflow, self.drop, out);
        }
    }
}

/// The master's link to [`Nodes`].
pub struct NodesLink(pub Arc<Mutex<Nodes>>);

impl CanLink for NodesLink {
    fn send(&mut self, frame: &CanFrame) -> io::Result<()> {
        self.0
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .deliver(frame);
        Ok(())
    }

    fn receive(&mut self, deadline_ns: u64) -> io::Result<Option<Received>> {
        let mut s = self.0.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            if let Some(frame) = s.queue.pop_front() {
                return Ok(Some(Received {
                    frame,
                    at_ns: Some(s.clock_ns),
                }));
            }
            if s.stepped || s.clock_ns >= deadline_ns {
                return Ok(None);
            }
            let next = deadline_ns.min(s.clock_ns + 100_000);
            s.tick(next);
        }
    }

    fn now_ns(&self) -> u64 {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).clock_ns
    }
}
