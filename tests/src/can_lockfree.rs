//! A lockstep CAN link that takes no lock, for the test that proves the CANopen cycle
//! takes none (`tests/runtime_no_lock.rs`, `cycle-under-seccomp canopen`): the simulated
//! nodes live inside the link ([`LockFreeLink`] owns its [`Nodes`], no `Mutex` between the
//! cycle and them), and what other threads tell it — the time the engine's step clock
//! moved to, a frame identifier to lose (a cable pulled), a node to reset as another
//! master would — reaches it through atomics ([`LinkControl`]).

use std::io;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;

use gantry::canopen::{CanLink, Received};
use gantry_drives::canopen::nmt::{NmtCommand, NmtFrame, NmtTarget};
use gantry_drives::canopen::{CanFrame, NodeId};
use gantry_sim::canopen::CanNode;

use crate::can_rig::Nodes;

/// What other threads set for the link, read with atomics only.
#[derive(Debug, Default)]
pub struct LinkControl {
    /// The engine's step clock: the time the bus moves to (ns).
    pub clock_ns: AtomicU64,
    /// Set when the engine's clock moves the bus (after the bring-up).
    pub stepped: AtomicBool,
    /// Frames with this identifier do not reach the master (0: none).
    pub drop: AtomicU32,
    /// A node to reset (NMT reset node) before the next frame, as another master would
    /// (0: none).
    pub reset_node: AtomicU8,
    /// Frames lost to the link's full queue.
    pub overflow: AtomicU64,
    /// Boot-up messages the master received once stepped (a node reset, by another
    /// master or by gantry's restore).
    pub boot_ups: AtomicU64,
}

/// The master's link onto nodes it owns.
pub struct LockFreeLink {
    nodes: Nodes,
    control: Arc<LinkControl>,
}

impl LockFreeLink {
    /// `nodes` at time 0 and the handle other threads steer the link by.
    pub fn new(nodes: Vec<CanNode>) -> (Self, Arc<LinkControl>) {
        let control = Arc::new(LinkControl::default());
        (
            Self {
                nodes: Nodes::new(nodes),
                control: control.clone(),
            },
            control,
        )
    }

    /// Takes in what other threads set: the time, the frames lost, a reset.
    fn follow(&mut self) {
        let c = &self.control;
        self.nodes.drop = match c.drop.load(Ordering::Relaxed) {
            0 => None,
            id => u16::try_from(id).ok(),
        };
        if c.stepped.load(Ordering::Acquire) {
            self.nodes.stepped = true;
            self.nodes.tick(c.clock_ns.load(Ordering::Acquire));
        }
        let reset = c.reset_node.swap(0, Ordering::AcqRel);
        if let Ok(node) = NodeId::new(reset) {
            if reset != 0 {
                let f = NmtFrame {
                    command: NmtCommand::ResetNode,
                    target: NmtTarget::Node(node),
                };
                self.nodes.deliver(&f.emit());
            }
        }
        c.overflow.store(self.nodes.overflow, Ordering::Relaxed);
    }
}

impl CanLink for LockFreeLink {
    fn send(&mut self, frame: &CanFrame) -> io::Result<()> {
        self.follow();
        self.nodes.deliver(frame);
        Ok(())
    }

    fn receive(&mut self, deadline_ns: u64) -> io::Result<Option<Received>> {
        self.follow();
        loop {
            if let Some(frame) = self.nodes.queue.pop_front() {
                // CiA 301 §7.2.8.3.2.1: a boot-up is 0x700 + node id with one byte 0.
                let boot_up = (0x701..=0x77F).contains(&frame.id()) && frame.data() == [0];
                if boot_up && self.nodes.stepped {
                    self.control.boot_ups.fetch_add(1, Ordering::Relaxed);
                }
                return Ok(Some(Received {
                    frame,
                    at_ns: Some(self.nodes.clock_ns),
                }));
            }
            if self.nodes.stepped || self.nodes.clock_ns >= deadline_ns {
                return Ok(None);
            }
            let next = deadline_ns.min(self.nodes.clock_ns + 100_000);
            self.nodes.tick(next);
        }
    }

    fn now_ns(&self) -> u64 {
        if self.control.stepped.load(Ordering::Acquire) {
            self.control
                .clock_ns
                .load(Ordering::Acquire)
                .max(self.nodes.clock_ns)
        } else {
            self.nodes.clock_ns
        }
    }
}
