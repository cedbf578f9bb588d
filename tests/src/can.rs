//! A small CANopen master for the vcan tests (tests/tests/vcan_*.rs): gantry-link's
//! SocketCAN socket with gantry-drives' NMT frames and SDO client, driven in real time
//! (the SDO machine's clock is `CLOCK_MONOTONIC`). Every frame received is kept, so a
//! test can ask afterwards what the bus carried.
//!
//! The vcan tests run where a vcan interface exists: in the VM of `deploy/vm/` (the build
//! machines' kernels have no CAN), or on a host whose kernel has vcan. They fail, never
//! skip, when the interface is missing.

use std::time::Duration;

use gantry_drives::canopen::cob_id::{CobId, NodeId};
use gantry_drives::canopen::nmt::{NmtCommand, NmtFrame, NmtTarget};
use gantry_drives::canopen::sdo::{
    DownloadMode, Multiplexer, Outcome, SdoClient, SdoConfig, UploadMode,
};
use gantry_drives::canopen::CanFrame;
use gantry_link::can_socket::{monotonic_ns, CanSocket, Received};

/// The bytes an SDO client holds: the largest object the tests move, the simulated
/// node's 64 KiB recorder 0x2F00 (`tests/tests/sdo_bench_vcan.rs`).
pub const SDO_BUFFER: usize = 1 << 16;

/// A test's master on one CAN interface.
pub struct CanMaster {
    socket: CanSocket,
    /// Every frame received, in order.
    pub seen: Vec<Received>,
}

impl CanMaster {
    /// Opens `interface`; panics with the socket's error (naming the interface) when it
    /// cannot: a vcan test that cannot reach its interface fails.
    pub fn open(interface: &str) -> Self {
        match CanSocket::open(interface) {
            Ok(socket) => Self {
                socket,
                seen: Vec::new(),
            },
            Err(e) => {
                panic!("{e} — the vcan tests run in the VM: deploy/vm/run (deploy/test.sh does it)")
            }
        }
    }

    /// Sends a frame.
    pub fn send(&self, frame: &CanFrame) {
        if let Err(e) = self.socket.send(frame) {
            panic!("sending {frame:?}: {e}");
        }
    }

    /// Sends an NMT command.
    pub fn nmt(&self, command: NmtCommand, node: NodeId) {
        self.send(
            &NmtFrame {
                command,
                target: NmtTarget::Node(node),
            }
            .emit(),
        );
    }

    /// Receives until a frame satisfies `want` or `timeout` passes; every frame goes to
    /// [`CanMaster::seen`].
    pub fn wait_for(
        &mut self,
        timeout: Duration,
        mut want: impl FnMut(&CanFrame) -> bool,
    ) -> Option<CanFrame> {
        let deadline = monotonic_ns() + timeout.as_nanos() as u64;
        loop {
            match self.socket.recv_until(deadline) {
                Ok(Some(r)) => {
                    self.seen.push(r);
                    if want(&r.frame) {
                        return Some(r.frame);
                    }
                }
                Ok(None) => return None,
                Err(e) => panic!("receiving: {e}"),
            }
        }
    }

    /// Receives everything for `span`; returns the frames that came.
    pub fn listen(&mut self, span: Duration) -> Vec<CanFrame> {
        let first = self.seen.len();
        let _ = self.wait_for(span, |_| false);
        self.seen[first..].iter().map(|r| r.frame).collect()
    }

    /// Runs one SDO transfer that `start` begins on `client` to its end.
    fn transfer(
        &mut self,
        client: &mut SdoClient<Vec<u8>>,
        start: impl FnOnce(&mut SdoClient<Vec<u8>>, u64),
    ) -> Outcome {
        let answer_id = CobId::SdoTx(client.node()).id();
        start(client, monotonic_ns());
        loop {
            while let Some(f) = client.transmit() {
                self.send(&f);
            }
            // 10 ms at most between looks at the client's timers.
            let deadline = monotonic_ns() + 10_000_000;
            let outcome = match self.socket.recv_until(deadline) {
                Ok(Some(r)) => {
                    self.seen.push(r);
                    if r.frame.id() == answer_id {
                        client.receive(&r.frame, monotonic_ns())
                    } else {
                        None
                    }
                }
                Ok(None) => client.poll(monotonic_ns()),
                Err(e) => panic!("receiving: {e}"),
            };
            if let Some(outcome) = outcome {
                // The last confirmation (e.g. a block upload's end response) still goes out.
                while let Some(f) = client.transmit() {
                    self.send(&f);
                }
                return outcome;
            }
        }
    }

    /// An SDO client of `node` with the default timing (1 s timeout, blocks of 127, CRC).
    pub fn client(node: NodeId) -> SdoClient<Vec<u8>> {
        match SdoClient::new(node, SdoConfig::default(), vec![0u8; SDO_BUFFER]) {
            Ok(c) => c,
            Err(e) => panic!("SDO client: {e}"),
        }
    }

    /// Uploads `index:sub` from `node`: the data, or the outcome that was not an upload.
    pub fn upload(
        &mut self,
        node: NodeId,
        index: u16,
        sub: u8,
        mode: UploadMode,
    ) -> Result<Vec<u8>, Outcome> {
        self.upload_with(SdoConfig::default(), node, index, sub, mode)
    }

    /// [`CanMaster::upload`] with a client of this configuration.
    pub fn upload_with(
        &mut self,
        config: SdoConfig,
        node: NodeId,
        index: u16,
        sub: u8,
        mode: UploadMode,
    ) -> Result<Vec<u8>, Outcome> {
        let mut client = match SdoClient::new(node, config, vec![0u8; SDO_BUFFER]) {
            Ok(c) => c,
            Err(e) => panic!("SDO client: {e}"),
        };
        let mux = Multiplexer::new(index, sub);
        let outcome = self.transfer(&mut client, |c, now| {
            if let Err(e) = c.upload(mux, mode, now) {
                panic!("upload {mux}: {e}");
            }
        });
        match outcome {
            Outcome::Uploaded { len, .. } => Ok(client.data()[..len].to_vec()),
            other => Err(other),
        }
    }

    /// Downloads `data` to `index:sub` of `node`.
    pub fn download(
        &mut self,
        node: NodeId,
        index: u16,
        sub: u8,
        data: &[u8],
        mode: DownloadMode,
    ) -> Result<(), Outcome> {
        let mut client = Self::client(node);
        let mux = Multiplexer::new(index, sub);
        let outcome = self.transfer(&mut client, |c, now| {
            if let Err(e) = c.download(mux, data, mode, now) {
                panic!("download {mux}: {e}");
            }
        });
        match outcome {
            Outcome::Downloaded { len, .. } if len == data.len() => Ok(()),
            other => Err(other),
        }
    }

    /// Downloads `data` and panics with the outcome if it is refused.
    pub fn write(&mut self, node: NodeId, index: u16, sub: u8, data: &[u8]) {
        if let Err(outcome) = self.download(node, index, sub, data, DownloadMode::Auto) {
            panic!(
                "writing 0x{index:04X}:{sub:02X} of node {}: {outcome:?}",
                node.get()
            );
        }
    }
}

/// A `gantry-sim --can` process, stopped (SIGTERM) and reaped when dropped.
pub struct CanSim {
    child: crate::netns::Reaped,
    config: std::path::PathBuf,
}

impl CanSim {
    /// Starts `gantry-sim --can interface` with the chain `config_toml` (written to a
    /// temporary file). Its output goes to a pipe read by [`CanSim::stop`].
    pub fn start(interface: &str, config_toml: &str) -> Self {
        let bin = match crate::netns::gantry_sim_binary() {
            Ok(b) => b,
            Err(e) => panic!("{e}"),
        };
        let config = std::env::temp_dir().join(format!(
            "gantry-vcan-sim-{}-{}.toml",
            std::process::id(),
            monotonic_ns()
        ));
        if let Err(e) = std::fs::write(&config, config_toml) {
            panic!("{}: {e}", config.display());
        }
        let child = std::process::Command::new(&bin)
            .arg("--can")
            .arg(interface)
            .arg("--config")
            .arg(&config)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn();
        match child {
            Ok(c) => Self {
                child: crate::netns::Reaped::new(c),
                config,
            },
            Err(e) => panic!("{}: {e}", bin.display()),
        }
    }

    /// Stops it with SIGTERM; its exit status and everything it printed.
    pub fn stop(mut self) -> (std::process::ExitStatus, String) {
        let child = self.child.child();
        let _ = nix::sys::signal::kill(
            nix::unistd::Pid::from_raw(child.id() as i32),
            nix::sys::signal::Signal::SIGTERM,
        );
        let output = match self.child.take().wait_with_output() {
            Ok(o) => o,
            Err(e) => panic!("gantry-sim: {e}"),
        };
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        );
        (output.status, text)
    }
}

impl Drop for CanSim {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.config);
    }
}
