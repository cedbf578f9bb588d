//! An in-memory CAN bus for lockstep tests: the master (the test) and several
//! [`CanNode`]s, each with a transmit queue. Whenever frames wait, the bus arbitrates as
//! CAN does (ISO 11898-1: the lowest identifier wins; a sender's own frames leave in
//! order) and delivers the winner to every other participant at once, the master
//! included. With a bit rate, each frame occupies the bus for its worst-case length
//! (47 + 8·n bits plus stuff bits: 135 bits for 8 data bytes) and is received when it ends.
//!
//! A module that follows a servo's axis (the switch-cam inputs, [`CanNode::coupled_axis`])
//! is handed that servo's position before every tick and every frame it gets, and gets
//! them after the other nodes: at a SYNC the servo first runs its loops to the SYNC, then
//! the module samples its cams at that position — the inputs its TPDO carries and the
//! position the servo's TPDO carries agree to the count, as on EtherCAT
//! ([`follow_axis`]; `gantry-sim --can` delivers in the same order).

use std::collections::VecDeque;

use gantry_drives::canopen::frame::frame_bits;
use gantry_drives::canopen::CanFrame;

use super::node::CanNode;

/// Who sent a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Sender {
    /// The master (the test).
    Master,
    /// Node at this position in [`CanBus::nodes`].
    Node(usize),
}

/// A frame as the bus carried it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Delivered {
    /// When its last bit was on the bus (ns).
    pub at_ns: u64,
    /// Who sent it.
    pub from: Sender,
    /// The frame.
    pub frame: CanFrame,
}

/// The bus.
#[derive(Debug)]
pub struct CanBus {
    nodes: Vec<CanNode>,
    /// Transmit queues: 0 the master's, 1 + i node i's.
    queues: Vec<VecDeque<CanFrame>>,
    bitrate: Option<u32>,
    free_at_ns: u64,
    now_ns: u64,
    received: Vec<Delivered>,
    log: Vec<Delivered>,
    /// Whether [`CanBus::log`] keeps every frame (a bus that runs for hours does not).
    keep_log: bool,
}

impl CanBus {
    /// A bus with these nodes and no bit timing (every frame arrives at once).
    pub fn new(nodes: Vec<CanNode>) -> Self {
        let queues = (0..=nodes.len())
            .map(|_| VecDeque::with_capacity(256))
            .collect();
        Self {
            nodes,
            queues,
            bitrate: None,
            free_at_ns: 0,
            now_ns: 0,
            received: Vec::with_capacity(4096),
            log: Vec::new(),
            keep_log: true,
        }
    }

    /// Whether the bus keeps every frame it carried for [`CanBus::log`] (the default); a
    /// bus that runs for as long as a service does keeps none.
    pub fn with_log(mut self, keep: bool) -> Self {
        self.keep_log = keep;
        self
    }

    /// Models a bit rate (bit/s): frames take their worst-case time on the bus.
    pub fn with_bitrate(mut self, bits_per_s: u32) -> Self {
        self.bitrate = Some(bits_per_s.max(1));
        self
    }

    /// The nodes.
    pub fn nodes(&self) -> &[CanNode] {
        &self.nodes
    }

    /// Node `i`.
    pub fn node(&self, i: usize) -> Option<&CanNode> {
        self.nodes.get(i)
    }

    /// Node `i`, mutable.
    pub fn node_mut(&mut self, i: usize) -> Option<&mut CanNode> {
        self.nodes.get_mut(i)
    }

    /// The bus time (ns): the last `run`'s time, or when the last frame ended if later.
    pub fn now_ns(&self) -> u64 {
        self.now_ns.max(self.free_at_ns)
    }

    /// The master queues `frame`; it goes on the next [`CanBus::run`].
    pub fn send(&mut self, frame: CanFrame) {
        if let Some(q) = self.queues.first_mut() {
            q.push_back(frame);
        }
    }

    /// Lets time pass to `now_ns`: every node ticks, then frames are arbitrated and
    /// delivered until no one has anything to send.
    pub fn run(&mut self, now_ns: u64) {
        self.now_ns = self.now_ns.max(now_ns);
        let now = self.now_ns();
        for (pass, i) in delivery_order(self.nodes.len()) {
            if follows_axis(&self.nodes, i) != pass {
                continue;
            }
            follow_axis(&mut self.nodes, i);
            let Some(n) = self.nodes.get_mut(i) else {
                continue;
            };
            let out = n.tick(now);
            if let Some(q) = self.queues.get_mut(i + 1) {
                q.extend(out.iter().copied());
            }
        }
        while let Some(winner) = self.arbitrate() {
            let Some(frame) = self.queues.get_mut(winner).and_then(VecDeque::pop_front) else {
                break;
            };
            let start = self.now_ns.max(self.free_at_ns);
            let end = match self.bitrate {
                Some(b) => start + frame_bits(frame.len()) * 1_000_000_000 / u64::from(b),
                None => start,
            };
            self.free_at_ns = end;
            let from = if winner == 0 {
                Sender::Master
            } else {
                Sender::Node(winner - 1)
            };
            let d = Delivered {
                at_ns: end,
                from,
                frame,
            };
            if self.keep_log {
                self.log.push(d);
            }
            if from != Sender::Master {
                self.received.push(d);
            }
            for (pass, i) in delivery_order(self.nodes.len()) {
                if from == Sender::Node(i) || follows_axis(&self.nodes, i) != pass {
                    continue;
                }
                follow_axis(&mut self.nodes, i);
                let Some(n) = self.nodes.get_mut(i) else {
                    continue;
                };
                let out = n.receive(&frame, end);
                if let Some(q) = self.queues.get_mut(i + 1) {
                    q.extend(out.iter().copied());
                }
            }
        }
    }

    /// The queue whose head frame wins arbitration: the lowest identifier; between equal
    /// identifiers (which CAN forbids between senders) the master, then the lower node.
    fn arbitrate(&self) -> Option<usize> {
        self.queues
            .iter()
            .enumerate()
            .filter_map(|(i, q)| q.front().map(|f| (f.id(), i)))
            .min()
            .map(|(_, i)| i)
    }

    /// Frames the nodes sent since the last call, in bus order (what the master received).
    pub fn take_received(&mut self) -> Vec<Delivered> {
        std::mem::take(&mut self.received)
    }

    /// Every frame the bus carried, in order (none without [`CanBus::with_log`]).
    pub fn log(&self) -> &[Delivered] {
        &self.log
    }
}

/// The order in which `n` nodes get a tick or a frame: `(pass, i)` for both passes over
/// the nodes in bus order; pass `false` serves the nodes that follow no axis, pass `true`
/// those that follow one ([`follows_axis`]), so a module samples its servo's position
/// after the servo has run to the same time.
pub fn delivery_order(n: usize) -> impl Iterator<Item = (bool, usize)> {
    [false, true]
        .into_iter()
        .flat_map(move |pass| (0..n).map(move |i| (pass, i)))
}

/// Whether node `i` follows a servo's axis.
pub fn follows_axis(nodes: &[CanNode], i: usize) -> bool {
    nodes.get(i).is_some_and(|n| n.coupled_axis().is_some())
}

/// If node `i` follows a servo's axis, hands it that servo's present position (a module
/// whose servo is not on the bus keeps the last position it had, none at first: its
/// cams rest).
pub fn follow_axis(nodes: &mut [CanNode], i: usize) {
    let Some(axis) = nodes.get(i).and_then(CanNode::coupled_axis) else {
        return;
    };
    let position = nodes
        .iter()
        .find(|n| n.node() == axis)
        .and_then(CanNode::axis_position);
    if let (Some(p), Some(n)) = (position, nodes.get_mut(i)) {
        n.sense_axis(p);
    }
}
