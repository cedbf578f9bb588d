//! The test as a CANopen master on the in-memory bus: NMT, SYNC, PDOs, and SDO through
//! `gantry_drives::canopen::SdoClient` (the master's own client), in lockstep.
#![allow(dead_code)]

use gantry_drives::canopen::heartbeat::{Heartbeat, NmtState};
use gantry_drives::canopen::nmt::{NmtCommand, NmtFrame, NmtTarget};
use gantry_drives::canopen::sdo::{
    AbortCode, DownloadMode, Multiplexer, Outcome, SdoClient, SdoConfig, UploadMode,
};
use gantry_drives::canopen::sync::Sync;
use gantry_drives::canopen::{CanFrame, NodeId};
use gantry_sim::canopen::bus::Delivered;
use gantry_sim::canopen::{CanBus, CanNode, CanNodeConfig};

/// 1 ms.
pub const MS: u64 = 1_000_000;

/// Node id `n`.
pub fn id(n: u8) -> NodeId {
    NodeId::new(n).unwrap()
}

/// A frame.
pub fn frame(cob: u16, data: &[u8]) -> CanFrame {
    CanFrame::new(u32::from(cob), data).unwrap()
}

/// The master side of a bus.
pub struct Master {
    /// The bus with the nodes.
    pub bus: CanBus,
    /// Bus time (ns).
    pub now: u64,
    /// Frames the nodes sent, not yet looked at.
    pub inbox: Vec<Delivered>,
    /// SYNC counter (0: SYNC without counter).
    pub sync_overflow: u8,
    sync_counter: u8,
}

impl Master {
    /// Nodes with these ids (default servo, heartbeat 100 ms), not yet booted.
    pub fn new(ids: &[u8]) -> Self {
        let nodes = ids
            .iter()
            .map(|&n| CanNode::new(CanNodeConfig::servo(id(n))).unwrap())
            .collect();
        Self::with_nodes(nodes)
    }

    /// A bus with `nodes`.
    pub fn with_nodes(nodes: Vec<CanNode>) -> Self {
        Self {
            bus: CanBus::new(nodes),
            now: 0,
            inbox: Vec::new(),
            sync_overflow: 0,
            sync_counter: 0,
        }
    }

    /// Node `i` (position on the bus).
    pub fn node(&self, i: usize) -> &CanNode {
        self.bus.node(i).unwrap()
    }

    /// Node `i`, mutable.
    pub fn node_mut(&mut self, i: usize) -> &mut CanNode {
        self.bus.node_mut(i).unwrap()
    }

    /// Lets `dt` ns pass; what the nodes sent is added to the inbox and returned.
    pub fn step(&mut self, dt: u64) -> Vec<Delivered> {
        self.now += dt;
        self.bus.run(self.now);
        let got = self.bus.take_received();
        self.inbox.extend(got.iter().copied());
        got
    }

    /// Sends frames now; returns what the nodes answered.
    pub fn send(&mut self, frames: &[CanFrame]) -> Vec<Delivered> {
        for f in frames {
            self.bus.send(*f);
        }
        self.step(0)
    }

    /// An NMT command.
    pub fn nmt(&mut self, command: NmtCommand, node: Option<u8>) -> Vec<Delivered> {
        let target = match node {
            Some(n) => NmtTarget::Node(id(n)),
            None => NmtTarget::All,
        };
        self.send(&[NmtFrame { command, target }.emit()])
    }

    /// The next SYNC frame (with the counter when `sync_overflow` is set).
    pub fn sync_frame(&mut self) -> CanFrame {
        if self.sync_overflow == 0 {
            return Sync::new().emit();
        }
        self.sync_counter = Sync::next_counter(self.sync_counter, self.sync_overflow).unwrap();
        Sync::with_counter(self.sync_counter).unwrap().emit()
    }

    /// Drains the inbox.
    pub fn take_inbox(&mut self) -> Vec<Delivered> {
        std::mem::take(&mut self.inbox)
    }

    /// Runs an SDO transfer with the master's client to completion (time advancing by
    /// 0.1 ms a round), the client's outcome.
    fn transfer(
        &mut self,
        client: &mut SdoClient<Vec<u8>>,
        start: impl FnOnce(&mut SdoClient<Vec<u8>>, u64),
    ) -> Outcome {
        start(client, self.now);
        for _ in 0..200_000 {
            while let Some(f) = client.transmit() {
                self.bus.send(f);
            }
            let got = self.step(0);
            for d in &got {
                if let Some(o) = client.receive(&d.frame, self.now) {
                    // Frames the client queued last (a final ack) go out too.
                    while let Some(f) = client.transmit() {
                        self.bus.send(f);
                    }
                    self.step(0);
                    return o;
                }
            }
            self.now += 100_000;
            if let Some(o) = client.poll(self.now) {
                while let Some(f) = client.transmit() {
                    self.bus.send(f);
                }
                self.step(0);
                return o;
            }
        }
        panic!("SDO transfer did not end");
    }

    /// SDO download of `data` to `node` `index`:`sub` in `mode`.
    pub fn download(
        &mut self,
        node: u8,
        index: u16,
        sub: u8,
        data: &[u8],
        mode: DownloadMode,
    ) -> Result<(), AbortCode> {
        let mut client = client(node);
        let mux = Multiplexer::new(index, sub);
        match self.transfer(&mut client, |c, now| {
            c.download(mux, data, mode, now).unwrap()
        }) {
            Outcome::Downloaded { len, .. } => {
                assert_eq!(len, data.len());
                Ok(())
            }
            Outcome::Aborted { code, .. } => Err(code),
            o => panic!("download ended with {o:?}"),
        }
    }

    /// Expedited/segmented download (as CiA 301 devices expect: `Auto`).
    pub fn write(&mut self, node: u8, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.download(node, index, sub, data, DownloadMode::Auto)
    }

    /// SDO upload from `node` `index`:`sub` in `mode`.
    pub fn upload(
        &mut self,
        node: u8,
        index: u16,
        sub: u8,
        mode: UploadMode,
    ) -> Result<Vec<u8>, AbortCode> {
        let mut client = client(node);
        let mux = Multiplexer::new(index, sub);
        match self.transfer(&mut client, |c, now| c.upload(mux, mode, now).unwrap()) {
            Outcome::Uploaded { len, .. } => Ok(client.data()[..len].to_vec()),
            Outcome::Aborted { code, .. } => Err(code),
            o => panic!("upload ended with {o:?}"),
        }
    }

    /// Normal upload.
    pub fn read(&mut self, node: u8, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
        self.upload(node, index, sub, UploadMode::Normal)
    }

    /// Normal upload of a u16.
    pub fn read_u16(&mut self, node: u8, index: u16, sub: u8) -> u16 {
        let v = self.read(node, index, sub).unwrap();
        u16::from_le_bytes([v[0], v[1]])
    }
}

/// The master's SDO client for `node` (timeout 50 ms).
pub fn client(node: u8) -> SdoClient<Vec<u8>> {
    let config = SdoConfig {
        timeout_ns: 50 * MS,
        ..SdoConfig::default()
    };
    // The recorder 0x2F00 of the large-upload tests is 64 KiB.
    SdoClient::new(id(node), config, vec![0; 1 << 16]).unwrap()
}

/// Heartbeats (boot-up included) of `node` among `frames`.
pub fn heartbeats(frames: &[Delivered], node: u8) -> Vec<(u64, NmtState)> {
    frames
        .iter()
        .filter_map(|d| Heartbeat::parse(&d.frame).ok().map(|h| (d.at_ns, h)))
        .filter(|(_, h)| h.node.get() == node)
        .map(|(t, h)| (t, h.state))
        .collect()
}

/// Frames on `cob` among `frames`.
pub fn on(frames: &[Delivered], cob: u16) -> Vec<CanFrame> {
    frames
        .iter()
        .filter(|d| d.frame.id() == cob)
        .map(|d| d.frame)
        .collect()
}
