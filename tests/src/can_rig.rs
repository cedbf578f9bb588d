//! gantry's CANopen bus over simulated nodes in this process, driven from one test
//! thread, in lockstep: the in-memory CAN bus ([`gantry_sim::canopen::CanBus`]: arbitration
//! and the bit rate's frame timing) behind the master's [`CanLink`] ([`MemLink`]), and the
//! engine, the controller and a [`StepClock`] that moves the bus' time one cycle per cycle,
//! as [`crate::rig::Rig`] does for EtherCAT.
//!
//! Time: during the bring-up the link runs its own clock (a wait for a frame lets the bus'
//! time pass up to the deadline, so the nodes' SDO answers, boot-ups and timeouts come as
//! they would); once the engine runs ([`MemBus::stepped`]) the step clock moves it, and an
//! exchange receives what the bus delivered by the cycle's reply window (what would arrive
//! later is late for this cycle, as on a wire). Its deadline, on the host's clock, is not
//! used: a lockstep bus has answered before the exchange looks.

use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Mutex, MutexGuard};

use gantry::canopen::bring_up::StartError;
use gantry::canopen::{CanLink, CanopenBus, Received};
use gantry::config::Config;
use gantry::runtime::bus::CycleBus;
use gantry::runtime::clock::{reply_window_ns, StepClock};
use gantry::runtime::controller::{CommandHandle, Controller};
use gantry::runtime::cycle::Cycle;
use gantry::runtime::engine::Engine;
use gantry::runtime::protocol::Snapshot;
use gantry_drives::canopen::{CanFrame, NodeId};
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::state::AxisState;
use gantry_sim::canopen::bus::Delivered;
use gantry_sim::canopen::{CanBus, CanNode, CanNodeConfig};

/// Longest the link lets its own clock run in one step while waiting (bring-up).
const IDLE_STEP_NS: u64 = 100_000;

/// The simulated bus as the link and the test share it.
pub struct MemBus {
    /// The in-memory CAN bus and its nodes.
    pub bus: CanBus,
    /// Frames the nodes sent that the master has not taken yet, in bus order.
    pending: VecDeque<Delivered>,
    /// The link's clock (ns).
    clock_ns: u64,
    /// Stepped by the engine's clock: (cycle start, reply window).
    stepped: Option<(u64, u64)>,
    /// Frames the master does not receive (a test's fault: a node's heartbeat lost).
    drop: Vec<u16>,
    /// Frames dropped so far.
    pub dropped: u64,
}

impl MemBus {
    /// Moves the bus to `to_ns` and collects what the nodes sent.
    fn run(&mut self, to_ns: u64) {
        self.clock_ns = self.clock_ns.max(to_ns);
        self.bus.run(self.clock_ns);
        for d in self.bus.take_received() {
            if self.drop.contains(&d.frame.id()) {
                self.dropped += 1;
            } else {
                self.pending.push_back(d);
            }
        }
    }

    /// From now on the engine's clock moves the bus, one cycle of `period_ns` at a time.
    pub fn stepped(&mut self, period_ns: u64) {
        self.stepped = Some((self.clock_ns, reply_window_ns(period_ns)));
    }

    /// A new cycle starts at `to_ns` (the step clock's advance).
    pub fn cycle_at(&mut self, to_ns: u64) {
        if let Some((start, _)) = self.stepped.as_mut() {
            *start = to_ns;
        }
        self.run(to_ns);
    }

    /// The master no longer receives frames with this identifier (or does again).
    pub fn drop_frames(&mut self, id: u16, drop: bool) {
        self.drop.retain(|d| *d != id);
        if drop {
            self.drop.push(id);
        }
    }

    /// Sends `frame` as another master would (the test's own NMT command, say).
    pub fn inject(&mut self, frame: CanFrame) {
        self.bus.send(frame);
        let now = self.clock_ns;
        self.run(now);
    }

    /// The node with id `node`.
    pub fn node(&self, node: u8) -> &CanNode {
        self.bus
            .nodes()
            .iter()
            .find(|n| n.node().get() == node)
            .unwrap_or_else(|| panic!("no node {node}"))
    }

    /// The node with id `node`, mutable.
    pub fn node_mut(&mut self, node: u8) -> &mut CanNode {
        let i = self
            .bus
            .nodes()
            .iter()
            .position(|n| n.node().get() == node)
            .unwrap_or_else(|| panic!("no node {node}"));
        self.bus.node_mut(i).expect("node")
    }

    /// The link's clock (ns).
    pub fn now_ns(&self) -> u64 {
        self.clock_ns
    }
}

/// The shared bus.
pub type SharedBus = Arc<Mutex<MemBus>>;

/// Locks the shared bus.
pub fn lock(bus: &SharedBus) -> MutexGuard<'_, MemBus> {
    bus.lock().unwrap_or_else(|e| e.into_inner())
}

/// The master's link onto the in-memory bus.
pub struct MemLink(SharedBus);

impl MemLink {
    /// A bus of `nodes`, at `bitrate` bit/s (None: frames take no time), and its link.
    pub fn new(nodes: Vec<CanNode>, bitrate: Option<u32>) -> (Self, SharedBus) {
        let mut bus = CanBus::new(nodes);
        if let Some(b) = bitrate {
            bus = bus.with_bitrate(b);
        }
        let shared = Arc::new(Mutex::new(MemBus {
            bus,
            pending: VecDeque::with_capacity(4096),
            clock_ns: 0,
            stepped: None,
            drop: Vec::new(),
            dropped: 0,
        }));
        (Self(shared.clone()), shared)
    }
}

impl CanLink for MemLink {
    fn send(&mut self, frame: &CanFrame) -> io::Result<()> {
        lock(&self.0).bus.send(*frame);
        Ok(())
    }

    fn receive(&mut self, deadline_ns: u64) -> io::Result<Option<Received>> {
        let mut s = lock(&self.0);
        loop {
            let now = s.clock_ns;
            s.run(now);
            let limit = match s.stepped {
                Some((start, window)) => start + window,
                None => deadline_ns,
            };
            if s.pending.front().is_some_and(|d| d.at_ns <= limit) {
                let Some(d) = s.pending.pop_front() else {
                    return Ok(None);
                };
                if s.stepped.is_none() {
                    s.clock_ns = s.clock_ns.max(d.at_ns);
                }
                return Ok(Some(Received {
                    frame: d.frame,
                    at_ns: Some(d.at_ns),
                }));
            }
            if s.stepped.is_some() || now >= deadline_ns {
                return Ok(None);
            }
            s.clock_ns = deadline_ns.min(now + IDLE_STEP_NS);
        }
    }

    fn now_ns(&self) -> u64 {
        lock(&self.0).clock_ns
    }
}

/// A CANopen configuration: one axis per node in `nodes` (5 mm ball screws on 2^17-count
/// motors, 200 mm/s), `pdo` layout, cycle `cycle_us`, 1 Mbit/s, on the in-memory bus.
pub fn can_config(nodes: &[u8], cycle_us: u32, pdo: &str) -> Config {
    can_config_with(nodes, cycle_us, pdo, "")
}

/// [`can_config`] with more `[bus]` lines.
pub fn can_config_with(nodes: &[u8], cycle_us: u32, pdo: &str, bus: &str) -> Config {
    let mut text = format!(
        "[bus]\nkind = \"canopen\"\ninterface = \"mem0\"\nbitrate = 1000000\n\
         cycle_us = {cycle_us}\n{bus}\n"
    );
    for (i, node) in nodes.iter().enumerate() {
        text += &format!(
            "[[axis]]\nname = \"a{i}\"\nnode = {node}\npdo = \"{pdo}\"\n\
             scaling = {{ counts_per_motor_rev = 131072, units_per_load_rev = 5.0 }}\n\
             max = {{ speed = 200.0, acceleration = 2000.0, jerk = 20000.0 }}\n"
        );
    }
    Config::parse(&text, "can.toml").unwrap_or_else(|e| panic!("{e}"))
}

/// Simulated servos with these node ids (heartbeat every 100 ms, as the configuration's
/// default asks for anyway).
pub fn servos(ids: &[u8]) -> Vec<CanNode> {
    ids.iter()
        .map(|&n| {
            CanNode::new(CanNodeConfig::servo(NodeId::new(n).expect("node id")))
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
