//! The in-process CANopen simulator as a link the library's CANopen bus is brought up on:
//! simulated nodes ([`gantry_sim::canopen::CanNode`]) on the in-memory CAN bus
//! ([`CanBus`]: arbitration, and the bit rate's frame timing), reached through the
//! master's [`CanLink`] ([`MemLink`]). Two ways to run it:
//!
//! - **Lockstep** ([`MemLink::new`]; the tests' `CanRig` and `gantry demo --bus canopen`):
//!   the bus runs on a clock of its own. During the bring-up a wait for a frame lets the
//!   bus' time pass up to its deadline, so the nodes' SDO answers, boot-ups and timeouts
//!   come as they would; once the engine runs ([`MemBus::stepped`]) the engine's step
//!   clock moves it one cycle per cycle ([`MemBus::cycle_at`]), and an exchange receives
//!   what the bus delivered by the cycle's reply window (what would arrive later is late
//!   for this cycle, as on a wire).
//! - **Wall clock** ([`MemLink::wall_clock`]; `gantry run` with `[bus] kind = "canopen"`
//!   and `simulator = "sim.toml"`): the link's clock is CLOCK_MONOTONIC; the bus' time is
//!   the time since the link opened; a receive lets the nodes run (at least every tick of
//!   the chain's cycle) and, when no frame has reached the master yet, sleeps — really —
//!   until the last bit of the frames on their way, the next tick or its deadline. A
//!   frame is received when its last bit is on the bus, never before: 4 drives' PDOs and the SYNC take the
//!   same ~2 ms of a 1 Mbit/s cycle they take on a wire.
//!
//! The simulation runs in the thread that calls the link (the cycle thread under `gantry
//! run`): it is the far end of the wire, not gantry's cycle code, and it allocates (the
//! bus' queues). gantry's own CANopen code does not.

use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use gantry::canopen::bring_up::StartError;
use gantry::canopen::{CanLink, Received};
use gantry::config::Config;
use gantry::runtime::clock::{now_ns, reply_window_ns};
use gantry_drives::canopen::CanFrame;
use gantry_sim::canopen::bus::Delivered;
use gantry_sim::canopen::network::CanNetwork;
use gantry_sim::canopen::{CanBus, CanNode};
use gantry_sim::config::SimConfig;
use gantry_sim::plant::record::DriveRecord;
use nix::sys::time::TimeSpec;
use nix::time::{clock_nanosleep, ClockId, ClockNanosleepFlags};

/// Longest the link lets the bus' own clock run in one step while waiting (lockstep
/// bring-up).
const IDLE_STEP_NS: u64 = 100_000;

/// The wall-clock mode: where the bus' time 0 is on CLOCK_MONOTONIC, and how often the
/// nodes run at least while the link waits.
#[derive(Clone, Copy, Debug)]
struct Wall {
    origin_ns: u64,
    tick_ns: u64,
}

/// The simulated bus as the link and its holder (a test, the demo) share it.
pub struct MemBus {
    /// The in-memory CAN bus and its nodes.
    pub bus: CanBus,
    /// Frames the nodes sent that the master has not taken yet, in bus order.
    pending: VecDeque<Delivered>,
    /// The bus' clock (ns).
    clock_ns: u64,
    /// Stepped by the engine's clock: (cycle start, reply window).
    stepped: Option<(u64, u64)>,
    /// On the wall clock (`gantry run`).
    wall: Option<Wall>,
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

    /// The engine's clock no longer moves the bus (its cycle ended): the link's waits do
    /// again, as during the bring-up (the bus' shutdown, [`gantry::canopen::CanopenBus::shut_down`]).
    pub fn free_running(&mut self) {
        self.stepped = None;
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

    /// The node with id `node`. Panics if there is none (a test's mistake).
    pub fn node(&self, node: u8) -> &CanNode {
        self.bus
            .nodes()
            .iter()
            .find(|n| n.node().get() == node)
            .unwrap_or_else(|| panic!("no node {node}"))
    }

    /// The node with id `node`, mutable. Panics if there is none (a test's mistake).
    pub fn node_mut(&mut self, node: u8) -> &mut CanNode {
        let i = self
            .bus
            .nodes()
            .iter()
            .position(|n| n.node().get() == node)
            .unwrap_or_else(|| panic!("no node {node}"));
        self.bus.node_mut(i).expect("node")
    }

    /// The bus' clock (ns).
    pub fn now_ns(&self) -> u64 {
        self.clock_ns
    }

    /// What the drives of `config`'s axes recorded of the master's setpoints, in axis
    /// order, which is the CANopen bus' drive order (None: no such node, or no drive).
    pub fn records(&self, config: &Config) -> Vec<Option<DriveRecord>> {
        config
            .axes
            .iter()
            .map(|a| {
                self.bus
                    .nodes()
                    .iter()
                    .find(|n| Some(n.node().get()) == a.node)
                    .and_then(CanNode::servo)
                    .map(|s| *s.record())
            })
            .collect()
    }
}

/// The shared bus.
pub type SharedBus = Arc<Mutex<MemBus>>;

/// Locks the shared bus (its state is whole between two calls, even if a thread
/// panicked holding it).
pub fn lock(bus: &SharedBus) -> MutexGuard<'_, MemBus> {
    bus.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The master's link onto the in-memory bus.
pub struct MemLink(SharedBus);

impl MemLink {
    /// A bus of `nodes`, at `bitrate` bit/s (None: frames take no time), and its link, in
    /// lockstep.
    pub fn new(nodes: Vec<CanNode>, bitrate: Option<u32>) -> (Self, SharedBus) {
        Self::make(nodes, bitrate, None, true)
    }

    /// A bus of `nodes` at `bitrate` bit/s on the wall clock: the link's clock is
    /// CLOCK_MONOTONIC, the nodes run at least every `tick_ns` while the link waits, and
    /// the bus keeps no log of its frames (it runs for as long as `gantry run` does).
    pub fn wall_clock(
        nodes: Vec<CanNode>,
        bitrate: Option<u32>,
        tick_ns: u64,
    ) -> (Self, SharedBus) {
        let wall = Wall {
            origin_ns: now_ns(),
            tick_ns: tick_ns.max(IDLE_STEP_NS),
        };
        Self::make(nodes, bitrate, Some(wall), false)
    }

    fn make(
        nodes: Vec<CanNode>,
        bitrate: Option<u32>,
        wall: Option<Wall>,
        log: bool,
    ) -> (Self, SharedBus) {
        let mut bus = CanBus::new(nodes).with_log(log);
        if let Some(b) = bitrate {
            bus = bus.with_bitrate(b);
        }
        let shared = Arc::new(Mutex::new(MemBus {
            bus,
            pending: VecDeque::with_capacity(4096),
            clock_ns: 0,
            stepped: None,
            wall,
            drop: Vec::new(),
            dropped: 0,
        }));
        (Self(shared.clone()), shared)
    }

    /// The wall-clock receive: the bus runs to now; a frame whose last bit is on the bus
    /// by now is received; otherwise the thread sleeps until the frames on their way have
    /// ended, the next tick or `deadline_ns`, whichever is first.
    fn receive_wall(&mut self, wall: Wall, deadline_ns: u64) -> Option<Received> {
        loop {
            let next = {
                let mut s = lock(&self.0);
                let now = now_ns();
                s.run(now.saturating_sub(wall.origin_ns));
                let due = s.pending.front().map(|d| d.at_ns + wall.origin_ns);
                if due.is_some_and(|at| at <= now) {
                    let d = s.pending.pop_front()?;
                    return Some(Received {
                        frame: d.frame,
                        at_ns: Some(d.at_ns + wall.origin_ns),
                    });
                }
                if now >= deadline_ns {
                    return None;
                }
                // One wake-up for what is on its way (the TPDOs a SYNC asked for end
                // one after another): until the last of it has ended, not one per frame
                // — a host without real time is late for each wake-up.
                let mut next = deadline_ns.min(now + wall.tick_ns);
                if let Some(last) = s.pending.back() {
                    next = next.min(last.at_ns + wall.origin_ns);
                }
                next
            };
            sleep_until(next);
        }
    }
}

/// Sleeps until `at_ns` on CLOCK_MONOTONIC (an interrupted sleep returns early: the
/// caller looks again).
fn sleep_until(at_ns: u64) {
    let ts = TimeSpec::new(
        (at_ns / 1_000_000_000) as i64,
        (at_ns % 1_000_000_000) as i64,
    );
    let _ = clock_nanosleep(
        ClockId::CLOCK_MONOTONIC,
        ClockNanosleepFlags::TIMER_ABSTIME,
        &ts,
    );
}

impl CanLink for MemLink {
    /// Queues `frame`; on the wall clock it goes on the bus now (arbitrated against
    /// what the nodes have queued by now), as a controller's transmit buffer would send
    /// it, whatever the sending thread does next.
    fn send(&mut self, frame: &CanFrame) -> io::Result<()> {
        let mut s = lock(&self.0);
        s.bus.send(*frame);
        if let Some(wall) = s.wall {
            s.run(now_ns().saturating_sub(wall.origin_ns));
        }
        Ok(())
    }

    fn receive(&mut self, deadline_ns: u64) -> io::Result<Option<Received>> {
        let wall = lock(&self.0).wall;
        if let Some(wall) = wall {
            return Ok(self.receive_wall(wall, deadline_ns));
        }
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
        let s = lock(&self.0);
        if s.wall.is_some() {
            now_ns()
        } else {
            s.clock_ns
        }
    }
}

/// The nodes of the gantry-sim chain file `path` (a `node = N` per slave), in chain
/// order, and the chain's cycle (ns).
pub fn load_nodes(path: &str) -> Result<(Vec<CanNode>, u64), StartError> {
    let bad = |what: &'static str, e: String| StartError::Link {
        what,
        source: io::Error::new(io::ErrorKind::InvalidData, e),
    };
    let sim =
        SimConfig::load(path).map_err(|e| bad("the simulator's configuration", e.to_string()))?;
    let network = CanNetwork::from_config(&sim, path)
        .map_err(|e| bad("the simulated CANopen nodes", e.to_string()))?;
    Ok((network.into_nodes(), u64::from(sim.cycle_us) * 1000))
}

/// Opens the simulated nodes of `config`'s `[bus] simulator` at its bit rate, reached
/// in lockstep ([`MemLink::new`]) or on the wall clock ([`MemLink::wall_clock`]).
pub fn open(config: &Config, wall_clock: bool) -> Result<Option<(MemLink, SharedBus)>, StartError> {
    let Some(path) = &config.bus.simulator else {
        return Ok(None);
    };
    let (nodes, tick_ns) = load_nodes(path)?;
    Ok(Some(if wall_clock {
        MemLink::wall_clock(nodes, config.bus.bitrate, tick_ns)
    } else {
        MemLink::new(nodes, config.bus.bitrate)
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::canopen::cob_id::NodeId;
    use gantry_sim::canopen::CanNodeConfig;

    fn servo(n: u8) -> CanNode {
        CanNode::new(CanNodeConfig::servo(NodeId::new(n).unwrap())).unwrap()
    }

    /// On the wall clock the link's clock is CLOCK_MONOTONIC; a frame is received no
    /// earlier than its last bit is on the bus; with nothing coming a receive really
    /// waits for its deadline.
    #[test]
    fn the_wall_clock_link_receives_on_time_and_waits_for_its_deadline() {
        let (mut link, bus) = MemLink::wall_clock(vec![servo(5)], Some(1_000_000), 2_000_000);
        let t0 = now_ns();
        assert!(link.now_ns() >= t0 && link.now_ns() < t0 + 1_000_000_000);
        // The node boots on its first run: its boot-up message (0x705, 1 byte).
        let r = link.receive(t0 + 100_000_000).unwrap().expect("a boot-up");
        assert_eq!((r.frame.id(), r.frame.data()), (0x705, &[0u8][..]));
        let at = r.at_ns.unwrap();
        assert!(
            at >= t0 && at <= now_ns(),
            "received at {at}, before its end?"
        );
        // An SDO upload of 0x1000: request and answer are 8-byte frames, each at least
        // 111 bits (without stuff bits) at 1 Mbit/s, one after the other on the bus.
        let sent = now_ns();
        let request = CanFrame::new(0x605, &[0x40, 0x00, 0x10, 0, 0, 0, 0, 0]).unwrap();
        link.send(&request).unwrap();
        let r = link
            .receive(sent + 100_000_000)
            .unwrap()
            .expect("an answer");
        assert_eq!(r.frame.id(), 0x585);
        assert_eq!(
            r.frame.data().get(4..8),
            Some(&0x0002_0192u32.to_le_bytes()[..])
        );
        let came = now_ns();
        assert!(
            came >= sent + 2 * 111_000,
            "answered {} ns after the request",
            came - sent
        );
        assert!(r.at_ns.unwrap() <= came);
        // Nothing else is due within 5 ms (its heartbeat comes every 100 ms): the receive
        // returns at its deadline, not before.
        let from = now_ns();
        let deadline = from + 5_000_000;
        let got = link.receive(deadline).unwrap();
        assert!(now_ns() >= deadline, "returned early");
        assert!(got.is_none_or(|r| r.frame.id() == 0x705), "{got:?}");
        // A wall-clock bus keeps no log (it runs as long as the service).
        assert!(lock(&bus).bus.log().is_empty());
    }

    #[test]
    fn a_chain_without_node_ids_or_a_missing_file_is_refused_with_the_reason() {
        let e = load_nodes("/nonexistent/sim.toml").unwrap_err().to_string();
        assert!(
            e.starts_with("CANopen: the simulator's configuration"),
            "{e}"
        );
        let dir = std::env::temp_dir().join(format!("gantry-can-sim-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("sim.toml");
        std::fs::write(&path, "cycle_us = 2000\n[[slave]]\nkind = \"servo\"\n").unwrap();
        let e = load_nodes(&path.display().to_string()).unwrap_err();
        let chain = gantry::error_chain::Chain(&e).to_string();
        assert!(chain.contains("has no CANopen node id"), "{chain}");
        std::fs::write(
            &path,
            "cycle_us = 2000\n[[slave]]\nkind = \"servo\"\nnode = 3\n",
        )
        .unwrap();
        let (nodes, tick) = load_nodes(&path.display().to_string()).unwrap();
        assert_eq!(
            (nodes.len(), nodes[0].node().get(), tick),
            (1, 3, 2_000_000)
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
