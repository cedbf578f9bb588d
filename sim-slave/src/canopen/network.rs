//! The simulated CANopen nodes of one chain description on one CAN interface, sans-I/O:
//! what `gantry-sim --can IFACE` runs behind its socket.
//!
//! Every frame from the wire goes to every node; every frame a node sends goes to the wire
//! and to every other node, since on a CAN bus all nodes hear every frame (ISO 11898-1) —
//! one node's heartbeat is another's consumer input (CiA 301 §7.2.8.3.2.3). The kernel
//! never hands a socket the frames it sent itself, so this in-process delivery is what
//! lets the simulated nodes hear each other.
//!
//! Which slaves become nodes: every slave of the chain needs a CANopen node id
//! (`node = N` in its `[[slave]]`); a `servo` becomes a CiA 402 [`CanNode`], an `encoder`
//! a CiA 406 one, a `switches` module a CiA 401 one that follows its servo's node
//! ([`CanNodeConfig::from_slave`]). Frames and ticks reach the nodes in the bus's
//! [`delivery_order`], each switch-cam module handed its servo's position first
//! ([`follow_axis`]), as on the in-memory bus.

use std::collections::VecDeque;

use gantry_drives::canopen::cob_id::NodeId;
use gantry_drives::canopen::CanFrame;
use thiserror::Error;

use super::bus::{delivery_order, follow_axis, follows_axis};
use super::node::{CanNode, CanNodeConfig, CanNodeError, SlaveNodeError};
use crate::config::{SimConfig, SlaveConfig};

/// Frames one delivery round may queue (a block upload's 127 segments and the other
/// nodes' answers to them fit many times over).
pub const WORK_FRAMES: usize = 4096;

/// A chain that cannot be simulated on a CAN bus.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum CanNetworkError {
    /// A slave has no node id.
    #[error(
        "{path}: slave[{slave}] ({kind}) has no CANopen node id: give it `node = N` (1..=127) \
         to simulate it on a CAN bus"
    )]
    NoNodeId {
        /// The configuration file.
        path: String,
        /// Its position in the chain.
        slave: usize,
        /// Its kind.
        kind: &'static str,
    },
    /// A slave that cannot be a CANopen node (e.g. its cams).
    #[error("{path}: {source}")]
    Slave {
        /// The configuration file.
        path: String,
        /// Why.
        source: SlaveNodeError,
    },
    /// A node id out of 1..=127 (the configuration checks it; here for a hand-made one).
    #[error("{path}: slave[{slave}].node = {node}: a CANopen node id must be 1 to 127")]
    BadNodeId {
        /// The configuration file.
        path: String,
        /// Its position in the chain.
        slave: usize,
        /// The id given.
        node: u8,
    },
    /// A node could not be built.
    #[error("{path}: slave[{slave}]: {source}")]
    Node {
        /// The configuration file.
        path: String,
        /// Its position in the chain.
        slave: usize,
        /// Why.
        source: CanNodeError,
    },
    /// The chain is empty.
    #[error("{path}: no slaves to simulate")]
    Empty {
        /// The configuration file.
        path: String,
    },
}

/// Counters of the network.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NetworkCounters {
    /// Frames taken from the wire.
    pub received: u64,
    /// Frames the nodes sent.
    pub sent: u64,
    /// Frames not delivered to the other nodes because one round queued more than
    /// [`WORK_FRAMES`] (still sent to the wire).
    pub overflow: u64,
}

/// The nodes and the delivery between them.
#[derive(Debug)]
pub struct CanNetwork {
    nodes: Vec<CanNode>,
    /// Frames sent by a node (its position) still to be heard by the others.
    work: VecDeque<(usize, CanFrame)>,
    counters: NetworkCounters,
}

impl CanNetwork {
    /// The nodes of a chain description, in chain order; `path` names the file in errors.
    pub fn from_config(config: &SimConfig, path: &str) -> Result<Self, CanNetworkError> {
        if config.slaves.is_empty() {
            return Err(CanNetworkError::Empty { path: path.into() });
        }
        let mut nodes = Vec::with_capacity(config.slaves.len());
        for (slave, s) in config.slaves.iter().enumerate() {
            let kind = kind_name(s);
            let Some(id) = s.node() else {
                return Err(CanNetworkError::NoNodeId {
                    path: path.into(),
                    slave,
                    kind,
                });
            };
            NodeId::new(id).map_err(|_| CanNetworkError::BadNodeId {
                path: path.into(),
                slave,
                node: id,
            })?;
            let node_config = CanNodeConfig::from_slave(config, slave).map_err(|source| {
                CanNetworkError::Slave {
                    path: path.into(),
                    source,
                }
            })?;
            let n = CanNode::new(node_config).map_err(|source| CanNetworkError::Node {
                path: path.into(),
                slave,
                source,
            })?;
            nodes.push(n);
        }
        Ok(Self::new(nodes))
    }

    /// A network of these nodes.
    pub fn new(nodes: Vec<CanNode>) -> Self {
        Self {
            nodes,
            work: VecDeque::with_capacity(WORK_FRAMES),
            counters: NetworkCounters::default(),
        }
    }

    /// The nodes, in chain order.
    pub fn nodes(&self) -> &[CanNode] {
        &self.nodes
    }

    /// The nodes, for another bus to carry (the in-process in-memory bus).
    pub fn into_nodes(self) -> Vec<CanNode> {
        self.nodes
    }

    /// The nodes, mutable (a test injects what the wire cannot).
    pub fn nodes_mut(&mut self) -> &mut [CanNode] {
        &mut self.nodes
    }

    /// Counters.
    pub fn counters(&self) -> NetworkCounters {
        self.counters
    }

    /// A frame from the wire at `now_ns`: every node hears it; `send` gets every frame the
    /// nodes send in answer, in order (and the other nodes hear those too).
    pub fn receive(&mut self, frame: &CanFrame, now_ns: u64, send: &mut impl FnMut(&CanFrame)) {
        self.counters.received += 1;
        for (pass, i) in delivery_order(self.nodes.len()) {
            if follows_axis(&self.nodes, i) == pass {
                self.collect(i, now_ns, Some(frame), send);
            }
        }
        self.deliver(now_ns, send);
    }

    /// Time passes to `now_ns` (boot-up, heartbeats, timeouts, the drives' loops):
    /// `send` gets what the nodes send.
    pub fn tick(&mut self, now_ns: u64, send: &mut impl FnMut(&CanFrame)) {
        for (pass, i) in delivery_order(self.nodes.len()) {
            if follows_axis(&self.nodes, i) == pass {
                self.collect(i, now_ns, None, send);
            }
        }
        self.deliver(now_ns, send);
    }

    /// Node `i` takes `frame` (or only the time); what it sends goes to `send` and to
    /// the work queue for the others.
    fn collect(
        &mut self,
        i: usize,
        now_ns: u64,
        frame: Option<&CanFrame>,
        send: &mut impl FnMut(&CanFrame),
    ) {
        follow_axis(&mut self.nodes, i);
        let Some(node) = self.nodes.get_mut(i) else {
            return;
        };
        let out = match frame {
            Some(f) => node.receive(f, now_ns),
            None => node.tick(now_ns),
        };
        for f in out {
            send(f);
            self.counters.sent += 1;
            if self.work.len() < WORK_FRAMES {
                self.work.push_back((i, *f));
            } else {
                self.counters.overflow += 1;
            }
        }
    }

    /// The frames the nodes sent, heard by the other nodes (and their answers in turn),
    /// until none is left; bounded by [`WORK_FRAMES`].
    fn deliver(&mut self, now_ns: u64, send: &mut impl FnMut(&CanFrame)) {
        let mut rounds = 0usize;
        while let Some((from, frame)) = self.work.pop_front() {
            rounds += 1;
            if rounds > WORK_FRAMES {
                self.counters.overflow += 1 + self.work.len() as u64;
                self.work.clear();
                return;
            }
            for (pass, i) in delivery_order(self.nodes.len()) {
                if i != from && follows_axis(&self.nodes, i) == pass {
                    self.collect(i, now_ns, Some(&frame), send);
                }
            }
        }
    }
}

fn kind_name(s: &SlaveConfig) -> &'static str {
    match s {
        SlaveConfig::Servo(_) => "servo",
        SlaveConfig::Encoder { .. } => "encoder",
        SlaveConfig::Switches { .. } => "switches",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::canopen::cob_id::CobId;
    use gantry_drives::canopen::heartbeat::Heartbeat;

    fn network(text: &str) -> Result<CanNetwork, CanNetworkError> {
        let config = SimConfig::parse(text, "sim.toml").unwrap();
        CanNetwork::from_config(&config, "sim.toml")
    }

    fn collect(f: impl FnOnce(&mut dyn FnMut(&CanFrame))) -> Vec<CanFrame> {
        let mut out = Vec::new();
        f(&mut |frame: &CanFrame| out.push(*frame));
        out
    }

    #[test]
    fn every_servo_with_a_node_id_boots_and_says_so() {
        let mut net = network(
            "[[slave]]\nkind = \"servo\"\nnode = 3\n[[slave]]\nkind = \"servo\"\nnode = 9\n",
        )
        .unwrap();
        let out = collect(|send| net.tick(0, &mut |f| send(f)));
        // Boot-up: COB-ID 0x700 + node, one byte 0 (CiA 301 §7.2.8.3.2.2).
        let bootups: Vec<_> = out
            .iter()
            .filter_map(|f| Heartbeat::parse(f).ok())
            .map(|h| h.node.get())
            .collect();
        assert_eq!(bootups, vec![3, 9]);
        assert!(out.iter().all(|f| f.data() == [0]), "{out:?}");
        assert_eq!(net.nodes().len(), 2);
    }

    #[test]
    fn an_sdo_request_is_answered_by_its_node_alone() {
        let mut net = network(
            "[[slave]]\nkind = \"servo\"\nnode = 3\n[[slave]]\nkind = \"servo\"\nnode = 9\n",
        )
        .unwrap();
        let _ = collect(|send| net.tick(0, &mut |f| send(f)));
        // Upload 0x1000:00 from node 9.
        let node9 = NodeId::new(9).unwrap();
        let request = CanFrame::new(
            u32::from(CobId::SdoRx(node9).id()),
            &[0x40, 0x00, 0x10, 0, 0, 0, 0, 0],
        )
        .unwrap();
        let out = collect(|send| net.receive(&request, 1_000_000, &mut |f| send(f)));
        assert_eq!(out.len(), 1, "{out:?}");
        assert_eq!(out[0].id(), CobId::SdoTx(node9).id());
        // Expedited upload response, 4 bytes: the CiA 402 servo's device type 0x00020192.
        assert_eq!(
            out[0].data(),
            &[0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]
        );
    }

    #[test]
    fn nodes_hear_each_other() {
        let mut net = network(
            "[[slave]]\nkind = \"servo\"\nnode = 1\n[[slave]]\nkind = \"servo\"\nnode = 2\n",
        )
        .unwrap();
        let _ = collect(|send| net.tick(0, &mut |f| send(f)));
        // Node 2 consumes node 1's heartbeat within 300 ms (0x1016:01 = 1 << 16 | 300),
        // written by an expedited download from the wire.
        let node2 = NodeId::new(2).unwrap();
        let value = (1u32 << 16 | 300).to_le_bytes();
        let write = CanFrame::new(
            u32::from(CobId::SdoRx(node2).id()),
            &[
                0x23, 0x16, 0x10, 0x01, value[0], value[1], value[2], value[3],
            ],
        )
        .unwrap();
        let out = collect(|send| net.receive(&write, 1_000_000, &mut |f| send(f)));
        assert_eq!(out[0].data()[0], 0x60, "download confirmed: {out:?}");
        // Node 1 beats every 100 ms; its heartbeats reach node 2 in-process only, so
        // node 2 never reports the heartbeat lost (EMCY 0x8130) while time passes...
        let mut emcys = Vec::new();
        for ms in (10..2000).step_by(10) {
            let out = collect(|send| net.tick(ms * 1_000_000, &mut |f| send(f)));
            emcys.extend(out.into_iter().filter(|f| f.id() == 0x082));
        }
        assert!(emcys.is_empty(), "node 2 heard node 1: {emcys:?}");
        // ...and does once node 1 falls silent (heartbeat producer off).
        let node1 = NodeId::new(1).unwrap();
        let off = CanFrame::new(
            u32::from(CobId::SdoRx(node1).id()),
            &[0x2B, 0x17, 0x10, 0x00, 0, 0, 0, 0],
        )
        .unwrap();
        let _ = collect(|send| net.receive(&off, 2_000_000_000, &mut |f| send(f)));
        for ms in (2010..3000).step_by(10) {
            let out = collect(|send| net.tick(ms * 1_000_000, &mut |f| send(f)));
            emcys.extend(out.into_iter().filter(|f| f.id() == 0x082));
        }
        assert!(
            emcys.iter().any(|f| f.data()[..2] == [0x30, 0x81]),
            "EMCY 0x8130 from node 2: {emcys:?}"
        );
    }

    #[test]
    fn the_encoder_and_a_switch_cam_module_following_its_servo_are_nodes() {
        let mut net = network(
            "[[slave]]\nkind = \"switches\"\nnode = 4\naxis = 1\n[[slave.cam]]\ninput = 3\n\
             from = 1000\nto = 2000\n[[slave]]\nkind = \"servo\"\nnode = 3\n\
             start_position = 1500\n[[slave]]\nkind = \"encoder\"\nnode = 5\n",
        )
        .unwrap();
        let _ = collect(|send| net.tick(0, &mut |f| send(f)));
        let start = CanFrame::new(0, &[0x01, 0]).unwrap();
        let _ = collect(|send| net.receive(&start, 1_000_000, &mut |f| send(f)));
        let sync = CanFrame::new(0x80, &[]).unwrap();
        let out = collect(|send| net.receive(&sync, 2_000_000, &mut |f| send(f)));
        // TPDO1 of each: the servo at 1500, the cam on input 3 actuated there (the module
        // first in the chain samples after the servo), the encoder's counter at 0.
        let tpdo = |cob: u16| {
            out.iter()
                .find(|f| f.id() == cob)
                .map(|f| f.data().to_vec())
        };
        assert_eq!(
            tpdo(0x183).map(|d| d[2..6].to_vec()),
            Some(1500i32.to_le_bytes().to_vec())
        );
        assert_eq!(tpdo(0x184), Some(vec![0b1000]));
        assert_eq!(tpdo(0x185), Some(vec![0, 0, 0, 0]));
    }

    #[test]
    fn slaves_without_node_ids_or_canopen_nodes_are_refused_by_position() {
        let e = network("[[slave]]\nkind = \"servo\"\nnode = 3\n[[slave]]\nkind = \"servo\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("sim.toml: slave[1] (servo) has no CANopen node id"),
            "{e}"
        );
        let mut bad_cams = SimConfig::parse(
            "[[slave]]\nkind = \"servo\"\nnode = 3\n[[slave]]\nkind = \"switches\"\nnode = 4\naxis = 0\n",
            "sim.toml",
        )
        .unwrap();
        if let Some(SlaveConfig::Switches { cams, .. }) = bad_cams.slaves.get_mut(1) {
            let cam = crate::config::CamConfig {
                input: 9,
                from: 0,
                to: 1,
                normally_closed: false,
            };
            cams.push(cam);
        }
        let e = CanNetwork::from_config(&bad_cams, "sim.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "sim.toml: slave[1]: cam 0: input 9 does not exist (0 to 7)"
        );
        let e = CanNetwork::from_config(
            &SimConfig {
                cycle_us: 1000,
                slaves: Vec::new(),
            },
            "sim.toml",
        )
        .unwrap_err()
        .to_string();
        assert_eq!(e, "sim.toml: no slaves to simulate");
    }
}
