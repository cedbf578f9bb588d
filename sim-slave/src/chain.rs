//! The network: frames pass the slaves in order, each serving every datagram, as on a
//! line topology (ports 0→1). The first slave marks the frame as forwarded (the
//! locally-administered bit of the source address), as real ESCs do.
//!
//! The chain keeps the network's time (ns, advanced by [`SlaveChain::advance`] or
//! [`SlaveChain::tick`]). A frame is sent at the current time and reaches each slave a
//! little later ([`WireTiming`]); the slaves' DC units stamp it with their local clocks.

use thiserror::Error;

use crate::esc::command::Served;
use crate::esc::datagram::{self, DatagramError};
use crate::esc::dc::Arrival;
use crate::esc::frame::{Frame, FrameError};
use crate::fault::Faults;
use crate::slave::Slave;

/// Why a frame was not processed (it is then dropped, as a real network would).
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum ChainError {
    /// The frame is malformed.
    #[error("malformed frame: {0}")]
    Frame(#[from] FrameError),
    /// A datagram is malformed.
    #[error("malformed datagram: {0}")]
    Datagram(#[from] DatagramError),
    /// An injected fault lost the frame.
    #[error("frame lost (injected fault)")]
    Lost,
}

/// Propagation of a frame along the line (ns). A frame leaves the master, crosses a link
/// to slave 0's port 0, passes its processing unit to port 1 and the next link, and so on;
/// the last slave turns it round (its port 1 is closed) and the frame comes back through
/// every slave's port 1 → port 0 forwarding. Forward and return delays differ, as in real
/// ESCs, so a master that halves loop times is off by `(processing − forwarding) / 2` for
/// every hop with slaves behind it (the last hop turns round in the processing unit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WireTiming {
    /// One link (cable and both PHYs), either direction.
    pub link_ns: u64,
    /// Port 0 in → processing unit → port 1 out (on the last slave: back to port 0).
    pub processing_ns: u64,
    /// Port 1 in → port 0 out on the way back.
    pub forwarding_ns: u64,
}

impl Default for WireTiming {
    fn default() -> Self {
        Self {
            link_ns: 100,
            processing_ns: 180,
            forwarding_ns: 140,
        }
    }
}

/// Nanoseconds one byte occupies a 100BASE-TX wire.
pub const BYTE_NS: u64 = 80;
/// Bytes of a frame on the wire around what the chain sees: preamble and start delimiter
/// (8), frame check sequence (4) and the inter-frame gap (12) (IEEE 802.3 §3.1, §4.4).
pub const FRAME_OVERHEAD_BYTES: u64 = 24;
/// Shortest Ethernet frame without its check sequence (shorter frames are padded).
pub const MIN_FRAME_BYTES: u64 = 60;

/// How long a frame of `len` bytes (without check sequence) occupies the wire: the
/// network's time moves on by as much while it passes.
pub const fn frame_ns(len: usize) -> u64 {
    let len = len as u64;
    let len = if len < MIN_FRAME_BYTES {
        MIN_FRAME_BYTES
    } else {
        len
    };
    (len + FRAME_OVERHEAD_BYTES) * BYTE_NS
}

impl WireTiming {
    /// When a frame sent at `sent` passes slave `i` of `n`.
    pub fn arrival(&self, sent: u64, i: usize, n: usize) -> Arrival {
        let hop = self.link_ns.saturating_add(self.processing_ns);
        let at = |k: usize| {
            sent.saturating_add(self.link_ns)
                .saturating_add(hop.saturating_mul(k as u64))
        };
        let last = n.saturating_sub(1);
        let port1 = (i < last).then(|| {
            // Leaves the last slave, then crosses (last − i − 1) slaves and links back.
            let turned = at(last).saturating_add(self.processing_ns);
            let back = self.link_ns.saturating_add(self.forwarding_ns);
            turned
                .saturating_add(back.saturating_mul((last - i - 1) as u64))
                .saturating_add(self.link_ns)
        });
        Arrival {
            port0: at(i),
            port1,
        }
    }
}

/// Application periods run at most in one catch-up after the host stalled: a second at
/// 1 ms. A drive runs on its own clock, so a stall of the simulator is replayed period by
/// period, SYNC0 edges and application runs in their order; skipped, the drives would
/// have followed their setpoints in less time than the master gave them (a following
/// error the master did not cause, or setpoints taken with no run between them). A
/// longer stall means the run is broken anyway; replaying it would stall the simulator
/// again.
pub const MAX_CATCH_UP: u32 = 1000;

/// A line of slaves.
#[derive(Clone, Debug, Default)]
pub struct SlaveChain {
    slaves: Vec<Slave>,
    faults: Faults,
    /// The network's time (ns).
    now_ns: u64,
    /// The period boundary at which [`SlaveChain::run_until`] last ran the applications:
    /// a frame that carries the time past the next one leaves it due, not skipped.
    applications_ran_ns: Option<u64>,
    timing: WireTiming,
    /// Per slave: logical datagrams that wrote its process data.
    process_data_writes: Vec<u64>,
}

impl SlaveChain {
    /// A chain of these slaves, in wiring order: each is wired on port 0 (towards the
    /// master) and, except the last, on port 1 (towards the next).
    pub fn new(mut slaves: Vec<Slave>) -> Self {
        let n = slaves.len();
        for (i, s) in slaves.iter_mut().enumerate() {
            s.set_ports([true, i + 1 < n, false, false]);
        }
        Self {
            slaves,
            faults: Faults::default(),
            now_ns: 0,
            applications_ran_ns: None,
            timing: WireTiming::default(),
            process_data_writes: vec![0; n],
        }
    }

    /// Loses the next `n` frames (no reply at all, as with a broken cable or CRC error).
    pub fn drop_frames(&mut self, n: u32) {
        self.faults.drop_frames = n;
    }

    /// Loses the replies of the next `n` frames after the slaves served them (see
    /// [`Faults::drop_replies`]).
    pub fn drop_replies(&mut self, n: u32) {
        self.faults.drop_replies = n;
    }

    /// Pulls the cable in front of slave `k`: it and the slaves after it stop answering;
    /// slave `k - 1` closes its port 1. `None` plugs it back in (the slaves kept their
    /// configuration, as they kept their power).
    pub fn cut_before(&mut self, k: Option<usize>) {
        self.faults.cut_before = k;
        let reachable = self.faults.reachable(self.slaves.len());
        for (i, s) in self.slaves.iter_mut().enumerate() {
            s.set_ports([i < reachable, i + 1 < reachable, false, false]);
        }
    }

    /// Slave `k` stops exchanging process data (`None`: it resumes): it passes logical
    /// datagrams on without serving or counting them, see [`Faults::no_process_data`].
    pub fn stop_process_data(&mut self, k: Option<usize>) {
        self.faults.no_process_data = k;
    }

    /// The faults in force.
    pub fn faults(&self) -> Faults {
        self.faults
    }

    /// The same chain with these propagation delays.
    pub fn with_timing(mut self, timing: WireTiming) -> Self {
        self.timing = timing;
        self
    }

    /// The propagation delays.
    pub fn timing(&self) -> WireTiming {
        self.timing
    }

    /// The network's time (ns since the chain was made).
    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }

    /// Advances the network's time by `ns` (DC clocks and SYNC0) and runs the
    /// applications for as long.
    pub fn advance(&mut self, ns: u64) {
        self.advance_clocks(ns);
        self.run_applications(ns as f64 * 1e-9);
    }

    fn advance_clocks(&mut self, ns: u64) {
        self.now_ns = self.now_ns.saturating_add(ns);
        for s in &mut self.slaves {
            s.advance_to(self.now_ns);
        }
    }

    /// Per slave, how many logical datagrams (LWR, LRW) wrote its process data: what restarts its process-data watchdog. A real-time host compares
    /// these between frames to see the gaps each drive saw.
    pub fn process_data_writes(&self) -> &[u64] {
        &self.process_data_writes
    }

    /// The slaves.
    pub fn slaves(&self) -> &[Slave] {
        &self.slaves
    }

    /// What each device recorded of the setpoints it took, in chain order (`None` for
    /// devices that are no drive): what tests judge the master by, and what
    /// [`crate::plant::record::write_records`] writes.
    pub fn records(&self) -> Vec<Option<crate::plant::record::DriveRecord>> {
        self.slaves
            .iter()
            .map(|s| s.device().record().copied())
            .collect()
    }

    /// Brings the network to time `t_ns`: the applications run once for every whole
    /// `period_ns` of network time passed (at most [`MAX_CATCH_UP`] of them after a stall:
    /// beyond that the rest is skipped, not replayed), the clocks go exactly to `t_ns`. Real-time runs
    /// call this before every frame, so DC clocks and SYNC0 follow the host's clock to the
    /// nanosecond rather than in whole periods. A boundary that a frame's own time on the
    /// wire carried the clocks past ([`SlaveChain::process`]) runs now, late by that much:
    /// a device's application timer fires during a frame too.
    pub fn run_until(&mut self, t_ns: u64, period_ns: u64) {
        let period_ns = period_ns.max(1);
        // Without a run of its own yet, the applications count as run at the last boundary.
        let after = *self
            .applications_ran_ns
            .get_or_insert(self.now_ns / period_ns * period_ns);
        let mut boundary = (after / period_ns + 1) * period_ns;
        let mut runs = 0;
        while boundary <= t_ns {
            if runs == MAX_CATCH_UP {
                // The rest of a long stall is skipped.
                self.applications_ran_ns = Some(t_ns / period_ns * period_ns);
                break;
            }
            // The clocks were brought to the last frame's time, mid-period; the
            // applications still run whole periods.
            if boundary > self.now_ns {
                self.advance_clocks(boundary - self.now_ns);
            }
            self.run_applications(period_ns as f64 * 1e-9);
            self.applications_ran_ns = Some(boundary);
            boundary += period_ns;
            runs += 1;
        }
        if t_ns > self.now_ns {
            self.advance_clocks(t_ns - self.now_ns);
        }
    }

    /// Runs `dt_s` seconds of every slave's application; the network's time advances as
    /// much (rounded to ns).
    pub fn tick(&mut self, dt_s: f64) {
        // The cast saturates (negative and NaN give 0).
        self.advance_clocks((dt_s * 1e9).round() as u64);
        self.run_applications(dt_s);
        // Whoever ticks keeps the applications' time: `run_until` starts afresh.
        self.applications_ran_ns = None;
    }

    /// The applications, then the couplings: every device that watches another slave's
    /// axis (switch cams) gets that slave's position as it is *after* this step, so the
    /// inputs of both agree in the next frame.
    fn run_applications(&mut self, dt_s: f64) {
        for s in &mut self.slaves {
            s.tick(dt_s);
        }
        for i in 0..self.slaves.len() {
            let position = self
                .slaves
                .get(i)
                .and_then(|s| s.device().coupled_axis())
                .and_then(|axis| self.slaves.get(axis))
                .and_then(|s| s.device().axis_position());
            if let (Some(p), Some(s)) = (position, self.slaves.get_mut(i)) {
                s.couple(p);
            }
        }
    }

    /// Slave `i`, mutable (device models and tests set its inputs).
    pub fn slave_mut(&mut self, i: usize) -> Option<&mut Slave> {
        self.slaves.get_mut(i)
    }

    /// Passes `frame` (a whole Ethernet frame) through every slave in place. The frame is
    /// sent at the network's current time; the time then moves on by as long as it
    /// occupies the wire ([`frame_ns`]), lost or not: a master's next frame cannot start
    /// earlier, and a device's timers (EEPROM, AL transitions) run while the master polls.
    pub fn process(&mut self, frame: &mut [u8]) -> Result<(), ChainError> {
        let result = self.pass(frame);
        self.advance_clocks(frame_ns(frame.len()));
        result
    }

    fn pass(&mut self, frame: &mut [u8]) -> Result<(), ChainError> {
        // Check the whole frame before any slave touches it: a frame that is malformed
        // half-way must not be half processed.
        datagram::validate(Frame::new_checked(&*frame)?.payload())?;
        if self.faults.lose_frame() {
            return Err(ChainError::Lost);
        }
        let reachable = self.faults.reachable(self.slaves.len());
        if reachable == 0 && self.faults.cut_before.is_some() {
            // The cable at the master is pulled: nothing comes back.
            return Err(ChainError::Lost);
        }
        let mut f = Frame::new_unchecked(&mut *frame);
        let slaves = self.slaves.get_mut(..reachable).unwrap_or_default();
        for (i, slave) in slaves.iter_mut().enumerate() {
            // The last slave reached turns the frame round.
            slave.frame_arrives(self.timing.arrival(self.now_ns, i, reachable));
        }
        // Each datagram passes the slaves in turn. A slave's state depends only on the
        // datagrams it has served, so this leaves frame and slaves as serving slave by
        // slave would (and is what the wire does: a long frame's first datagram reaches
        // the next slave before its last has left this one); each datagram is decoded
        // once, not once per slave.
        let (faults, writes) = (self.faults, &mut self.process_data_writes);
        datagram::for_each_mut(f.payload_mut(), |mut d| {
            let logical = d.command().is_logical();
            for (i, slave) in slaves.iter_mut().enumerate() {
                if logical && !faults.exchanges_process_data(i) {
                    continue;
                }
                let served = slave.serve(&mut d);
                if logical && matches!(served, Served::Written | Served::ReadWritten) {
                    if let Some(n) = writes.get_mut(i) {
                        *n += 1;
                    }
                }
            }
        })?;
        if reachable > 0 {
            f.mark_forwarded();
        }
        if self.faults.lose_reply() {
            return Err(ChainError::Lost);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::esc::datagram::{Command, Datagram};
    use crate::esc::frame::ETHERTYPE;
    use crate::esc::registers::{AL_CONTROL, AL_STATUS, STATION_ADDRESS, TYPE};
    use crate::esc::sii::{control, DeviceDescription};

    fn description(product: u32) -> DeviceDescription {
        DeviceDescription {
            vendor_id: 0x0A5A,
            product_code: product,
            revision: 1,
            serial: product,
            order_code: format!("SIM-{product}"),
            name: format!("device {product}"),
            mailbox: None,
            mailbox_protocols: 0,
            sync_managers: vec![],
            fmmus: vec![],
            dc: false,
            tx_pdos: vec![],
            rx_pdos: vec![],
        }
    }

    fn chain(n: u32) -> SlaveChain {
        SlaveChain::new((0..n).map(|i| Slave::new(description(i))).collect())
    }

    /// A frame with one datagram.
    fn frame(cmd: Command, adp: u16, ado: u16, data: &[u8]) -> Vec<u8> {
        let dlen = 12 + data.len();
        let mut buf = vec![0u8; 16 + dlen];
        let mut f = Frame::new_unchecked(&mut buf[..]);
        f.set_dst([0xff; 6]);
        f.set_src([0x10; 6]);
        f.set_ethertype(ETHERTYPE);
        f.set_ecat_header(dlen);
        let mut d = Datagram::new_unchecked(f.payload_mut());
        d.set_command(cmd);
        d.set_adp(adp);
        d.set_ado(ado);
        d.set_len(data.len(), false, false);
        d.data_mut().copy_from_slice(data);
        buf
    }

    fn reply(buf: &[u8]) -> (Vec<u8>, u16) {
        let f = Frame::new_checked(buf).unwrap();
        let d = Datagram::new_checked(f.payload(), 0).unwrap();
        (d.data().to_vec(), d.wkc())
    }

    #[test]
    fn a_scan_counts_slaves_sets_addresses_and_reads_identity() {
        let mut c = chain(3);
        // Count: BRD 0x0000.
        let mut f = frame(Command::Brd, 0, TYPE, &[0, 0]);
        c.process(&mut f).unwrap();
        assert_eq!(reply(&f).1, 3);
        assert_eq!(f[6], 0x12, "forwarded frames carry the local bit");
        // Station addresses by position.
        for pos in 0..3u16 {
            let mut f = frame(
                Command::Apwr,
                0u16.wrapping_sub(pos),
                STATION_ADDRESS,
                &(0x1000 + pos).to_le_bytes(),
            );
            c.process(&mut f).unwrap();
            assert_eq!(reply(&f).1, 1);
        }
        // SII: product code (word 0x0A) of station 0x1002 through the EEPROM interface.
        let mut f = frame(Command::Fpwr, 0x1002, 0x0504, &0x0Au32.to_le_bytes());
        c.process(&mut f).unwrap();
        let mut f = frame(Command::Fpwr, 0x1002, 0x0502, &control::READ.to_le_bytes());
        c.process(&mut f).unwrap();
        // The EEPROM interface is busy (0x0502 bit 15) until the read is done.
        let mut f = frame(Command::Fprd, 0x1002, 0x0502, &[0; 2]);
        c.process(&mut f).unwrap();
        assert_eq!(reply(&f).0[1] & 0x80, 0x80, "busy");
        c.advance(crate::esc::sii::READ_NS);
        let mut f = frame(Command::Fprd, 0x1002, 0x0502, &[0; 2]);
        c.process(&mut f).unwrap();
        assert_eq!(reply(&f).0[1] & 0x80, 0, "done");
        let mut f = frame(Command::Fprd, 0x1002, 0x0508, &[0; 8]);
        c.process(&mut f).unwrap();
        let (data, wkc) = reply(&f);
        assert_eq!(wkc, 1);
        assert_eq!(u32::from_le_bytes(data[0..4].try_into().unwrap()), 2);
    }

    #[test]
    fn al_control_writes_change_state_and_refusals_latch() {
        let mut c = chain(2);
        let mut f = frame(Command::Bwr, 0, AL_CONTROL, &[2, 0]);
        c.process(&mut f).unwrap();
        assert_eq!(reply(&f).1, 2);
        let mut f = frame(Command::Brd, 0, AL_STATUS, &[0, 0]);
        c.process(&mut f).unwrap();
        assert_eq!(reply(&f).0, vec![2, 0], "both in PreOp");
        // PreOp → Op directly is refused with the error bit and code 0x0011.
        let mut f = frame(Command::Bwr, 0, AL_CONTROL, &[8, 0]);
        c.process(&mut f).unwrap();
        assert_eq!(c.slaves()[0].al_status(), 0x12);
        assert_eq!(c.slaves()[1].al_status_code().raw(), 0x0011);
    }

    #[test]
    fn dl_status_shows_the_line_topology() {
        use crate::esc::registers::DL_STATUS;
        let c = chain(2);
        let first = c.slaves()[0].memory().read_u16(DL_STATUS);
        let last = c.slaves()[1].memory().read_u16(DL_STATUS);
        assert_eq!(
            first & 0x0F30,
            0x0A30,
            "ports 0 and 1: link and communication"
        );
        assert_eq!(last & 0x0F30, 0x0610, "port 0 open, port 1 loop closed");
    }

    #[test]
    fn frames_reach_each_slave_later_and_come_back_on_port_1() {
        let t = WireTiming {
            link_ns: 100,
            processing_ns: 180,
            forwarding_ns: 140,
        };
        let a: Vec<_> = (0..3).map(|i| t.arrival(1_000, i, 3)).collect();
        assert_eq!(
            a.iter().map(|a| a.port0).collect::<Vec<_>>(),
            [1_100, 1_380, 1_660]
        );
        // The last slave turns the frame round at 1_840; slave 1 sees it on port 1 after
        // one link, slave 0 after another forwarding and link.
        assert_eq!(
            a.iter().map(|a| a.port1).collect::<Vec<_>>(),
            [Some(2_180), Some(1_940), None]
        );
    }

    #[test]
    fn only_dc_slaves_latch_and_count_receive_times() {
        use crate::esc::registers::{DC_RECEIVE_TIME_PORT0, FEATURES};
        let dc = |i| {
            let mut d = description(i);
            d.dc = true;
            Slave::new(d).with_dc_clock(0.0, 1_000_000 * u64::from(i))
        };
        let mut c = SlaveChain::new(vec![dc(1), Slave::new(description(2)), dc(3)]);
        c.advance(5_000);
        let mut f = frame(Command::Brd, 0, FEATURES, &[0, 0]);
        c.process(&mut f).unwrap();
        assert_eq!(reply(&f).0, vec![0x0C, 0x01], "OR of the feature bits");
        assert_eq!(c.slaves()[1].memory().read_u16(FEATURES) & 0x010C, 0);
        // Each frame moves the network's time on by its time on the wire.
        assert_eq!(c.now_ns(), 5_000 + frame_ns(f.len()));
        let sent = c.now_ns();
        let mut f = frame(Command::Bwr, 0, DC_RECEIVE_TIME_PORT0, &[0; 4]);
        c.process(&mut f).unwrap();
        assert_eq!(reply(&f).1, 2, "the slave without DC does not answer");
        let mut f = frame(Command::Aprd, 0, DC_RECEIVE_TIME_PORT0, &[0; 8]);
        c.process(&mut f).unwrap();
        let (data, wkc) = reply(&f);
        assert_eq!(wkc, 1);
        let p0 = u32::from_le_bytes(data[0..4].try_into().unwrap());
        let p1 = u32::from_le_bytes(data[4..8].try_into().unwrap());
        assert_eq!(p0, 1_000_000 + sent as u32 + 100);
        // Two hops out (link + processing), the turn in the last slave, one forwarding and
        // two links back.
        assert_eq!(p1 - p0, 2 * 280 + 180 + 140 + 2 * 100);
        let mut f = frame(Command::Aprd, 0xFFFF, DC_RECEIVE_TIME_PORT0, &[0; 4]);
        c.process(&mut f).unwrap();
        assert_eq!(reply(&f).1, 0);
    }

    #[test]
    fn advancing_time_drives_sync0() {
        use crate::esc::registers::{DC_ACTIVATION, DC_START_TIME_CYCLIC, DC_SYNC0_CYCLE_TIME};
        let mut d = description(1);
        d.dc = true;
        let mut c = SlaveChain::new(vec![Slave::new(d)]);
        for (ado, data) in [
            (DC_START_TIME_CYCLIC, 2_000_000u64.to_le_bytes().to_vec()),
            (DC_SYNC0_CYCLE_TIME, 1_000_000u32.to_le_bytes().to_vec()),
            (DC_ACTIVATION, vec![0x03]),
        ] {
            let mut f = frame(Command::Apwr, 0, ado, &data);
            c.process(&mut f).unwrap();
            assert_eq!(reply(&f).1, 1);
        }
        c.advance(1_000_000);
        assert_eq!(c.slaves()[0].sync0_events(), 0);
        c.tick(0.001);
        assert_eq!(c.slaves()[0].sync0_events(), 1);
        c.advance(10_500_000);
        assert_eq!(c.slaves()[0].sync0_events(), 11);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig {
            cases: 1000,
            rng_seed: proptest::test_runner::RngSeed::Fixed(7),
            failure_persistence: None,
            ..proptest::prelude::ProptestConfig::default()
        })]
        /// Any physical command on any part of the DC block, at any time, with any data:
        /// no panic.
        #[test]
        fn dc_accesses_never_panic(
            cmd in 0u8..16,
            adp in proptest::prelude::any::<u16>(),
            ado in 0x08F0u16..0x09C0,
            data in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..24),
            advance in proptest::prelude::any::<u64>(),
        ) {
            let dc = |i: u32| {
                let mut d = description(i);
                d.dc = i != 1;
                Slave::new(d).with_dc_clock(f64::from(i) * 300.0 - 300.0, u64::MAX / 2)
            };
            let mut c = SlaveChain::new((0..3).map(dc).collect());
            for ado in [ado, 0x0981, 0x0910] {
                let mut f = frame(Command::from(cmd), adp, ado, &data);
                let _ = c.process(&mut f);
                c.advance(advance >> 24);
            }
            c.advance(advance);
            c.advance(u64::MAX);
        }
    }

    /// A frame of several datagrams: (command, ADP, ADO, data).
    fn frame_of(datagrams: &[(u8, u16, u16, Vec<u8>)]) -> Vec<u8> {
        let dlen: usize = datagrams.iter().map(|d| 12 + d.3.len()).sum();
        let mut buf = vec![0u8; 16 + dlen];
        let mut f = Frame::new_unchecked(&mut buf[..]);
        f.set_dst([0xff; 6]);
        f.set_src([0x10; 6]);
        f.set_ethertype(ETHERTYPE);
        f.set_ecat_header(dlen);
        let mut at = 0;
        for (k, (cmd, adp, ado, data)) in datagrams.iter().enumerate() {
            let payload = f.payload_mut();
            let mut d = Datagram::new_unchecked(&mut payload[at..at + 12 + data.len()]);
            d.set_command(Command::from(*cmd));
            d.set_adp(*adp);
            d.set_ado(*ado);
            d.set_len(data.len(), false, k + 1 < datagrams.len());
            d.data_mut().copy_from_slice(data);
            at += 12 + data.len();
        }
        buf
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig {
            cases: 300,
            rng_seed: proptest::test_runner::RngSeed::Fixed(11),
            failure_persistence: None,
            ..proptest::prelude::ProptestConfig::default()
        })]
        /// The chain serves a frame datagram by datagram; the result is the same as
        /// serving it slave by slave (each slave every datagram, then the next slave):
        /// the same reply and the same slaves. The frame first gives the slaves station
        /// addresses, so that later datagrams of the same frame address them.
        #[test]
        fn serving_by_datagram_equals_serving_by_slave(
            datagrams in proptest::collection::vec(
                (
                    0u8..16,
                    proptest::sample::select(vec![0u16, 1, 0xFFFF, 0xFFFE, 0x1000, 0x1001, 0x1002]),
                    proptest::sample::select(vec![
                        0x0000u16, 0x0010, 0x0120, 0x0130, 0x0500, 0x0502, 0x0600, 0x0800,
                        0x0900, 0x0910, 0x0981, 0x1000, 0x1100,
                    ]),
                    proptest::collection::vec(proptest::prelude::any::<u8>(), 0..10),
                ),
                1..8,
            ),
        ) {
            use crate::catalog::{self, ServoOptions};
            let servo = |serial| catalog::servo(ServoOptions { serial, ..ServoOptions::default() });
            let mut c = SlaveChain::new(vec![servo(1), Slave::new(description(2)), servo(3)]);
            c.advance(12_345);
            let mut all: Vec<_> = (0..3u16)
                .map(|i| (2, 0u16.wrapping_sub(i), STATION_ADDRESS, (0x1000 + i).to_le_bytes().to_vec()))
                .collect();
            all.extend(datagrams);
            let mut f = frame_of(&all);
            let mut by_slave = f.clone();
            let mut slaves = c.slaves().to_vec();
            let sent = c.now_ns();
            c.process(&mut f).unwrap();
            let payload = &mut by_slave[16..];
            for (i, s) in slaves.iter_mut().enumerate() {
                s.frame_arrives(c.timing().arrival(sent, i, 3));
                datagram::for_each_mut(payload, |mut d| {
                    s.serve(&mut d);
                })
                .unwrap();
                s.advance_to(sent + frame_ns(f.len()));
            }
            proptest::prop_assert_eq!(c.now_ns(), sent + frame_ns(f.len()));
            Frame::new_unchecked(&mut by_slave[..]).mark_forwarded();
            proptest::prop_assert_eq!(f, by_slave);
            for (a, b) in c.slaves().iter().zip(&slaves) {
                proptest::prop_assert_eq!(format!("{a:?}"), format!("{b:?}"));
            }
        }
    }

    /// Real time brings the clocks to each frame's time, mid-period; the applications
    /// still run whole periods, so a device's time keeps up with the network's.
    #[test]
    fn run_until_runs_whole_application_periods() {
        use crate::catalog::{self, EncoderOptions};
        use crate::plant::DeviceModel;
        let encoder = catalog::encoder(EncoderOptions {
            serial: 1,
            counts_per_rev: 1000,
            shaft_speed_rev_s: 1.0,
        });
        let mut c = SlaveChain::new(vec![encoder]);
        // Frames every 0.3 ms for 100 ms, applications every 1 ms.
        for k in 1..=333u64 {
            c.run_until(k * 300_000, 1_000_000);
        }
        assert_eq!(
            c.now_ns(),
            99_900_000,
            "the clocks are at the last frame's time"
        );
        let DeviceModel::Encoder(e) = c.slaves()[0].device() else {
            panic!("an encoder");
        };
        // 99 whole periods at 1 rev/s and 1000 counts per rev: 99 counts (not 70 % of it).
        assert_eq!(e.position_counts(), 99);
        // A stall of 100 ms is replayed period by period: the device's time keeps up.
        c.run_until(200_000_000, 1_000_000);
        assert_eq!(c.now_ns(), 200_000_000);
        let DeviceModel::Encoder(e) = c.slaves()[0].device() else {
            panic!("an encoder");
        };
        assert_eq!(e.position_counts(), 200);
        // Beyond MAX_CATCH_UP periods the rest is skipped, and the clocks jump.
        let long = 200_000_000 + 5 * u64::from(MAX_CATCH_UP) * 1_000_000;
        c.run_until(long, 1_000_000);
        assert_eq!(c.now_ns(), long);
        let DeviceModel::Encoder(e) = c.slaves()[0].device() else {
            panic!("an encoder");
        };
        assert_eq!(e.position_counts(), 200 + i64::from(MAX_CATCH_UP));
    }

    #[test]
    fn a_boundary_a_frame_carried_the_clocks_past_still_runs() {
        use crate::catalog::{self, EncoderOptions};
        use crate::plant::DeviceModel;
        let encoder = catalog::encoder(EncoderOptions {
            serial: 1,
            counts_per_rev: 1000,
            shaft_speed_rev_s: 1.0,
        });
        let mut c = SlaveChain::new(vec![encoder]);
        // Each cycle the master's frame starts just before a boundary and is on the wire
        // across it (a lockstep master in that phase): 100 cycles, 100 application runs.
        let mut f = frame(Command::Brd, 0, TYPE, &[0, 0]);
        let lead = frame_ns(f.len()) / 2;
        for k in 1..=100u64 {
            c.run_until(k * 1_000_000 - lead, 1_000_000);
            let _ = c.process(&mut f);
        }
        c.run_until(100_500_000, 1_000_000);
        let DeviceModel::Encoder(e) = c.slaves()[0].device() else {
            panic!("an encoder");
        };
        assert_eq!(e.position_counts(), 100);
    }

    #[test]
    fn malformed_frames_are_dropped_untouched() {
        let mut c = chain(2);
        let mut f = frame(Command::Brd, 0, TYPE, &[0, 0]);
        f.truncate(f.len() - 3);
        let before = f.clone();
        assert!(c.process(&mut f).is_err());
        assert_eq!(f, before);
        let mut junk = vec![0u8; 5];
        assert!(matches!(c.process(&mut junk), Err(ChainError::Frame(_))));
    }

    #[test]
    fn a_lost_reply_did_its_work_on_the_way_out() {
        let mut c = chain(2);
        c.drop_replies(1);
        // APWR of a station address to the first slave: taken, but no reply.
        let mut f = frame(Command::Apwr, 0, 0x0010, &[0x34, 0x12]);
        assert_eq!(c.process(&mut f), Err(ChainError::Lost));
        let mut f = frame(Command::Aprd, 0, 0x0010, &[0, 0]);
        c.process(&mut f).unwrap();
        let (data, wkc) = reply(&f);
        assert_eq!((data, wkc), (vec![0x34, 0x12], 1), "the write happened");
    }

    #[test]
    fn injected_faults_lose_frames_and_cut_the_line() {
        use crate::esc::registers::DL_STATUS;
        let mut c = chain(3);
        c.drop_frames(2);
        for _ in 0..2 {
            let mut f = frame(Command::Brd, 0, TYPE, &[0, 0]);
            assert_eq!(c.process(&mut f), Err(ChainError::Lost));
        }
        let mut f = frame(Command::Brd, 0, TYPE, &[0, 0]);
        c.process(&mut f).unwrap();
        assert_eq!(reply(&f).1, 3, "the third frame passes again");
        // Cable pulled in front of slave 1: only slave 0 answers, and closes port 1.
        c.cut_before(Some(1));
        let mut f = frame(Command::Brd, 0, TYPE, &[0, 0]);
        c.process(&mut f).unwrap();
        assert_eq!(reply(&f).1, 1);
        assert_eq!(c.slaves()[0].memory().read_u16(DL_STATUS) & 0x0F30, 0x0610);
        c.cut_before(None);
        let mut f = frame(Command::Brd, 0, TYPE, &[0, 0]);
        c.process(&mut f).unwrap();
        assert_eq!(reply(&f).1, 3, "plugged back in");
        // The cable at the master pulled: nothing comes back.
        c.cut_before(Some(0));
        let mut f = frame(Command::Brd, 0, TYPE, &[0, 0]);
        assert_eq!(c.process(&mut f), Err(ChainError::Lost));
    }

    /// Sends one datagram to the chain; returns (data, WKC) of the reply.
    fn send(c: &mut SlaveChain, cmd: Command, adp: u16, ado: u16, data: &[u8]) -> (Vec<u8>, u16) {
        let mut f = frame(cmd, adp, ado, data);
        c.process(&mut f).unwrap();
        reply(&f)
    }

    /// AL status and AL status code of the first slave, as the master reads them.
    fn al(c: &mut SlaveChain) -> [u8; 6] {
        let (data, wkc) = send(c, Command::Aprd, 0, AL_STATUS, &[0; 6]);
        assert_eq!(wkc, 1);
        data.try_into().unwrap()
    }

    /// The servo's mailbox SyncManagers as its EEPROM describes them (SM0 receive, SM1
    /// send, 128 bytes each, mailbox mode).
    const MAILBOX_SMS: [u8; 16] = [
        0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00, //
        0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01, 0x00,
    ];

    /// The servo's process-data SyncManagers as a master sets them: SM2 (outputs at
    /// 0x1100, buffered, ECAT writes) and SM3 (inputs at 0x1400, buffered, ECAT reads) with
    /// these lengths.
    fn process_data_sms(c: &mut SlaveChain, outputs: u8, inputs: u8) {
        use crate::esc::registers::SM0;
        send(
            c,
            Command::Apwr,
            0,
            SM0 + 16,
            &[0x00, 0x11, outputs, 0, 0x64, 0, 1, 0],
        );
        send(
            c,
            Command::Apwr,
            0,
            SM0 + 24,
            &[0x00, 0x14, inputs, 0, 0x20, 0, 1, 0],
        );
    }

    /// A servo taken to PreOp the way a master does it.
    fn servo_in_preop() -> SlaveChain {
        use crate::catalog::{self, ServoOptions};
        use crate::esc::registers::SM0;
        let mut c = SlaveChain::new(vec![catalog::servo(ServoOptions::default())]);
        send(&mut c, Command::Apwr, 0, SM0, &MAILBOX_SMS);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[2, 0]);
        c.advance(2_000_000);
        assert_eq!(al(&mut c)[..2], [0x02, 0x00]);
        c
    }

    #[test]
    fn init_to_preop_needs_the_mailbox_and_takes_its_time() {
        use crate::catalog::{self, ServoOptions};
        use crate::esc::registers::SM0;
        let mut c = SlaveChain::new(vec![catalog::servo(ServoOptions::default())]);
        // No mailbox set up: refused at once, 0x0016 invalid mailbox configuration (PreOp).
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[2, 0]);
        assert_eq!(al(&mut c), [0x11, 0x00, 0, 0, 0x16, 0x00]);
        // The receive mailbox in the master-reads direction (control 0x22): still 0x0016.
        let mut wrong = MAILBOX_SMS;
        wrong[4] = 0x22;
        send(&mut c, Command::Apwr, 0, SM0, &wrong);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[0x12, 0]);
        assert_eq!(al(&mut c), [0x11, 0x00, 0, 0, 0x16, 0x00]);
        // Set up as the EEPROM says: accepted, the error cleared, the state still Init
        // until the firmware is done (2 ms).
        send(&mut c, Command::Apwr, 0, SM0, &MAILBOX_SMS);
        let asked = c.now_ns();
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[0x12, 0]);
        assert_eq!(al(&mut c), [0x01, 0x00, 0, 0, 0x00, 0x00]);
        c.advance(asked + 2_000_000 - 1 - c.now_ns());
        assert_eq!(al(&mut c)[0], 0x01, "1 ns before 2 ms: Init");
        c.advance(1);
        assert_eq!(al(&mut c), [0x02, 0x00, 0, 0, 0x00, 0x00], "PreOp at 2 ms");
    }

    #[test]
    fn syncmanagers_that_overlap_are_an_invalid_syncmanager_configuration() {
        use crate::esc::registers::SM0;
        let mut c = servo_in_preop();
        // SM2 buffered: its three buffers (3 × 6 bytes from 0x1100) run into SM3 at 0x1110.
        send(
            &mut c,
            Command::Apwr,
            0,
            SM0 + 16,
            &[0x00, 0x11, 6, 0, 0x64, 0, 1, 0],
        );
        send(
            &mut c,
            Command::Apwr,
            0,
            SM0 + 24,
            &[0x10, 0x11, 6, 0, 0x20, 0, 1, 0],
        );
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[4, 0]);
        assert_eq!(al(&mut c), [0x12, 0x00, 0, 0, 0x17, 0x00]);
    }

    #[test]
    fn safeop_is_refused_when_the_syncmanagers_do_not_match_the_mapping() {
        use crate::esc::registers::SM0;
        let mut c = servo_in_preop();
        // SM2 one byte short of the mapped 6 output bytes; SM3 right.
        process_data_sms(&mut c, 5, 6);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[4, 0]);
        assert_eq!(al(&mut c), [0x12, 0x00, 0, 0, 0x1D, 0x00]);
        // Right length, but the master-reads direction (control 0x60): outputs again.
        send(
            &mut c,
            Command::Apwr,
            0,
            SM0 + 16,
            &[0x00, 0x11, 6, 0, 0x60, 0, 1, 0],
        );
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[0x14, 0]);
        assert_eq!(al(&mut c)[4], 0x1D);
        process_data_sms(&mut c, 6, 4);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[0x14, 0]);
        assert_eq!(al(&mut c)[4], 0x1E, "now the inputs");
        send(
            &mut c,
            Command::Apwr,
            0,
            SM0 + 24,
            &[0x00, 0x14, 6, 0, 0x20, 0, 1, 0],
        );
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[0x14, 0]);
        assert_eq!(al(&mut c), [0x02, 0x00, 0, 0, 0, 0], "accepted, on its way");
        c.advance(10_000_000);
        assert_eq!(al(&mut c)[..2], [0x04, 0x00], "SafeOp after 10 ms");
    }

    /// Two TxPDOs of 10 × 0x6064 (80 bytes): each within the per-PDO limit, together past
    /// the device's 64-byte buffer; SM3 set to the 80 bytes is refused with 0x001E.
    #[test]
    fn safeop_is_refused_when_the_assigned_pdos_exceed_the_devices_buffer() {
        let mut c = servo_in_preop();
        let od = c
            .slave_mut(0)
            .and_then(Slave::object_dictionary_mut)
            .expect("CoE");
        let entry = 0x6064_0020u32.to_le_bytes();
        od.write(0x1C13, 0, &[0]).unwrap();
        for pdo in [0x1A00u16, 0x1A01] {
            od.write(pdo, 0, &[0]).unwrap();
            for sub in 1..=10 {
                od.write(pdo, sub, &entry).unwrap();
            }
            od.write(pdo, 0, &[10]).unwrap();
        }
        od.write(0x1C13, 2, &0x1A01u16.to_le_bytes()).unwrap();
        od.write(0x1C13, 0, &[2]).unwrap();
        process_data_sms(&mut c, 6, 80);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[4, 0]);
        assert_eq!(al(&mut c), [0x12, 0x00, 0, 0, 0x1E, 0x00]);
        // One PDO of the two (40 bytes) with SM3 at 40: accepted.
        let od = c
            .slave_mut(0)
            .and_then(Slave::object_dictionary_mut)
            .expect("CoE");
        od.write(0x1C13, 0, &[1]).unwrap();
        process_data_sms(&mut c, 6, 40);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[0x14, 0]);
        assert_eq!(al(&mut c), [0x02, 0x00, 0, 0, 0, 0], "accepted, on its way");
    }

    /// A servo in SafeOp with process data at 0x1100 (outputs) and 0x1400 (inputs).
    fn servo_in_safeop(activation: u8) -> SlaveChain {
        use crate::esc::registers::{DC_ACTIVATION, DC_START_TIME_CYCLIC, DC_SYNC0_CYCLE_TIME};
        let mut c = servo_in_preop();
        // SYNC0 (if activated) starts in 100 s.
        let start = (c.now_ns() + 100_000_000_000).to_le_bytes();
        send(&mut c, Command::Apwr, 0, DC_START_TIME_CYCLIC, &start);
        process_data_sms(&mut c, 6, 6);
        send(
            &mut c,
            Command::Apwr,
            0,
            DC_SYNC0_CYCLE_TIME,
            &1_000_000u32.to_le_bytes(),
        );
        send(&mut c, Command::Apwr, 0, DC_ACTIVATION, &[activation]);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[4, 0]);
        c.advance(10_000_000);
        assert_eq!(al(&mut c)[..2], [0x04, 0x00]);
        c
    }

    #[test]
    fn safeop_to_op_waits_for_valid_outputs_and_refuses_without_them() {
        let mut c = servo_in_safeop(0);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[8, 0]);
        c.advance(5_000_000);
        assert_eq!(
            al(&mut c)[..2],
            [0x04, 0x00],
            "no outputs yet: still SafeOp"
        );
        // Half the output buffer is not valid outputs.
        send(&mut c, Command::Apwr, 0, 0x1100, &[0x06, 0x00, 0x00]);
        c.advance(1_000_000);
        assert_eq!(
            al(&mut c),
            [0x04, 0x00, 0, 0, 0, 0],
            "a partial buffer does not count"
        );
        // The rest, to the buffer's last byte: the buffer is complete, the drive goes on.
        send(&mut c, Command::Apwr, 0, 0x1103, &[0x00, 0x00, 0x00]);
        assert_eq!(al(&mut c)[..2], [0x08, 0x00], "Op");
        // A drive that never gets outputs refuses after SafeopOpTimeout: 0x001B.
        let mut c = servo_in_safeop(0);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[8, 0]);
        // (The request's frame left 100 µs of margin for the frames' own time.)
        c.advance(crate::esc::al::SAFEOP_OP_TIMEOUT_NS - 100_000);
        assert_eq!(al(&mut c)[..2], [0x04, 0x00]);
        c.advance(100_000);
        assert_eq!(al(&mut c), [0x14, 0x00, 0, 0, 0x1B, 0x00]);
    }

    #[test]
    fn dc_mode_waits_for_sync0_and_a_bad_activation_is_an_invalid_dc_configuration() {
        use crate::esc::registers::DC_ACTIVATION;
        // Cyclic unit on, no SYNC signal: 0x0030 at PreOp → SafeOp.
        let mut c = servo_in_preop();
        process_data_sms(&mut c, 6, 6);
        send(&mut c, Command::Apwr, 0, DC_ACTIVATION, &[0x01]);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[4, 0]);
        assert_eq!(al(&mut c), [0x12, 0x00, 0, 0, 0x30, 0x00]);
        // SYNC0 on, but its start time is far ahead: with outputs, Op waits for SYNC0 and
        // gives up with 0x002D (no sync error).
        let mut c = servo_in_safeop(0x03);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[8, 0]);
        send(&mut c, Command::Apwr, 0, 0x1100, &[0; 6]);
        c.advance(10_000_000);
        assert_eq!(al(&mut c)[..2], [0x04, 0x00], "waiting for SYNC0");
        c.advance(crate::esc::al::SAFEOP_OP_TIMEOUT_NS);
        assert_eq!(al(&mut c), [0x14, 0x00, 0, 0, 0x2D, 0x00]);
        // SYNC0 pulsing (start time 0, already passed): Op once outputs came.
        let mut c = servo_in_preop();
        process_data_sms(&mut c, 6, 6);
        // The slave's system time is its local time (offset 0, drift 0): chain time.
        let start = c.now_ns().to_le_bytes();
        send(
            &mut c,
            Command::Apwr,
            0,
            crate::esc::registers::DC_START_TIME_CYCLIC,
            &start,
        );
        send(
            &mut c,
            Command::Apwr,
            0,
            crate::esc::registers::DC_SYNC0_CYCLE_TIME,
            &1_000_000u32.to_le_bytes(),
        );
        send(&mut c, Command::Apwr, 0, DC_ACTIVATION, &[0x03]);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[4, 0]);
        c.advance(10_000_000);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[8, 0]);
        send(&mut c, Command::Apwr, 0, 0x1100, &[0; 6]);
        c.advance(5_000_000);
        assert_eq!(al(&mut c)[..2], [0x08, 0x00]);
    }

    /// The servo's drive state and record.
    fn drive(
        c: &SlaveChain,
    ) -> (
        gantry_drives::cia402::State,
        crate::plant::record::DriveRecord,
        u16,
    ) {
        match c.slaves()[0].device() {
            crate::plant::DeviceModel::Servo(s) => (s.state(), *s.record(), s.error_code()),
            other => panic!("not a servo: {other:?}"),
        }
    }

    #[test]
    fn a_dc_drive_takes_its_outputs_at_sync0_and_counts_missed_and_doubled_setpoints() {
        use crate::esc::registers::{DC_ACTIVATION, DC_START_TIME_CYCLIC, DC_SYNC0_CYCLE_TIME};
        use gantry_drives::cia402::State;
        let mut c = servo_in_preop();
        process_data_sms(&mut c, 6, 6);
        // SYNC0 every 1 ms from half a period on: frames sent right after each whole
        // period arrive mid-period (each frame's wire time moves them 7 µs a period).
        let start = (c.now_ns() + 500_000).to_le_bytes();
        send(&mut c, Command::Apwr, 0, DC_START_TIME_CYCLIC, &start);
        send(
            &mut c,
            Command::Apwr,
            0,
            DC_SYNC0_CYCLE_TIME,
            &1_000_000u32.to_le_bytes(),
        );
        send(&mut c, Command::Apwr, 0, DC_ACTIVATION, &[0x03]);
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[4, 0]);
        let period = |c: &mut SlaveChain| {
            let t = c.now_ns();
            c.advance(1_000_000 - (t % 1_000_000));
        };
        for _ in 0..11 {
            period(&mut c);
        }
        assert_eq!(al(&mut c)[..2], [0x04, 0x00]);
        let out = |c: &mut SlaveChain, cw: u16, target: i32| {
            let mut b = cw.to_le_bytes().to_vec();
            b.extend(target.to_le_bytes());
            assert_eq!(send(c, Command::Apwr, 0, 0x1100, &b).1, 1);
        };
        // SafeOp: outputs are ignored (safe state), the drive stays where it is.
        out(&mut c, 0x06, 0);
        period(&mut c);
        assert_eq!(drive(&c).0, State::SwitchOnDisabled);
        // To Op with outputs every period; then enable (6, 7, 15) and move.
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[8, 0]);
        for _ in 0..6 {
            out(&mut c, 0x06, 0);
            period(&mut c);
        }
        assert_eq!(al(&mut c)[..2], [0x08, 0x00]);
        for (k, cw) in [0x06u16, 0x07, 0x0F, 0x0F, 0x0F, 0x0F, 0x0F, 0x0F]
            .into_iter()
            .enumerate()
        {
            out(&mut c, cw, 10 * k as i32);
            period(&mut c);
        }
        let (state, record, _) = drive(&c);
        assert_eq!(state, State::OperationEnabled);
        assert_eq!((record.sync_missed, record.sync_doubled), (0, 0));
        let taken = record.targets;
        assert!(taken >= 4, "{record:?}");
        // Two frames in one period: the first is overwritten before SYNC0 takes it.
        out(&mut c, 0x0F, 100);
        out(&mut c, 0x0F, 110);
        period(&mut c);
        let (_, record, _) = drive(&c);
        assert_eq!(record.sync_doubled, 1);
        assert_eq!(record.targets, taken + 1, "one setpoint taken at the edge");
        assert_eq!(
            record.max_target_step_counts, 20,
            "70 → 110 with the 100 between never taken: 40 counts over two master cycles"
        );
        assert_eq!(c.slaves()[0].sync_counters().cycle_time_too_small, 1);
        // A period without a frame: one missed setpoint, 0x1C32:0B = 3, still Op.
        period(&mut c);
        let (_, record, _) = drive(&c);
        assert_eq!(record.sync_missed, 1);
        assert_eq!(c.slaves()[0].sync_counters().sm_event_missed, 3);
        assert_eq!(al(&mut c)[..2], [0x08, 0x00]);
        // Three good periods bring the counter down to 0; then two misses in a row reach
        // the limit: sync error, out of Op with 0x001A, the drive faults (0x8700).
        for _ in 0..3 {
            out(&mut c, 0x0F, 110);
            period(&mut c);
        }
        assert_eq!(c.slaves()[0].sync_counters().sm_event_missed, 0);
        period(&mut c);
        assert_eq!(al(&mut c)[..2], [0x08, 0x00], "one miss is tolerated");
        period(&mut c);
        assert_eq!(al(&mut c), [0x14, 0x00, 0, 0, 0x1A, 0x00]);
        assert!(c.slaves()[0].sync_counters().sync_error);
        let (state, record, code) = drive(&c);
        assert_eq!((state, code), (State::Fault, 0x8700));
        assert_eq!(record.sync_missed, 3);
        // The master reads them by SDO: 0x1C32:0B (SM event missed), :20 (sync error),
        // :01 (sync type 2: SYNC0).
        let upload = |c: &mut SlaveChain, sub: u8, counter: u8| {
            let mut m = vec![0u8; 128];
            m[0] = 10;
            m[5] = crate::coe::MAILBOX_TYPE_COE | (counter << 4);
            m[6..8].copy_from_slice(&(crate::coe::COE_SDO_REQUEST << 12).to_le_bytes());
            m[8..12].copy_from_slice(&[0x40, 0x32, 0x1C, sub]);
            assert_eq!(send(c, Command::Apwr, 0, 0x1000, &m).1, 1);
            let (answer, wkc) = send(c, Command::Aprd, 0, 0x1080, &[0; 128]);
            assert_eq!(wkc, 1);
            assert_eq!(
                &answer[8..12],
                &[0x4B, 0x32, 0x1C, sub][..],
                "2-byte upload"
            );
            u16::from_le_bytes([answer[12], answer[13]])
        };
        assert_eq!(upload(&mut c, 0x0B, 1), 6);
        assert_eq!(upload(&mut c, 0x0C, 2), 1);
        assert_eq!(upload(&mut c, 0x01, 3), 2);
    }

    #[test]
    fn a_free_running_drive_takes_its_outputs_when_the_frame_wrote_them_and_only_in_op() {
        use gantry_drives::cia402::State;
        let mut c = servo_in_safeop(0);
        let out = |c: &mut SlaveChain, cw: u16| {
            let mut b = cw.to_le_bytes().to_vec();
            b.extend(0i32.to_le_bytes());
            send(c, Command::Apwr, 0, 0x1100, &b);
        };
        // SafeOp: ignored.
        out(&mut c, 0x06);
        c.tick(0.001);
        assert_eq!(drive(&c).0, State::SwitchOnDisabled);
        // The inputs are valid in SafeOp: the statusword (0x0240 | ...) is there.
        let (inputs, _) = send(&mut c, Command::Aprd, 0, 0x1400, &[0; 2]);
        assert_ne!(inputs, vec![0, 0], "statusword published in SafeOp");
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[8, 0]);
        c.advance(5_000_000);
        out(&mut c, 0x06);
        assert_eq!(al(&mut c)[..2], [0x08, 0x00]);
        // Op: each frame's outputs are taken when it completes the buffer, no matter
        // when the application's period falls; no SYNC0, nothing missed.
        out(&mut c, 0x06);
        c.tick(0.001);
        out(&mut c, 0x07);
        c.tick(0.001);
        assert_eq!(drive(&c).0, State::SwitchedOn);
        let (_, record, _) = drive(&c);
        assert_eq!((record.sync_missed, record.sync_doubled), (0, 0));
        // Back to SafeOp: the drive gets its safe outputs (controlword 0).
        send(&mut c, Command::Apwr, 0, AL_CONTROL, &[4, 0]);
        c.tick(0.001);
        assert_eq!(drive(&c).0, State::SwitchOnDisabled);
    }

    #[test]
    fn a_simple_terminal_in_device_emulation_mirrors_al_control_at_once() {
        use crate::catalog::{self, SwitchesOptions};
        let mut c = SlaveChain::new(vec![catalog::switches(SwitchesOptions::default()).unwrap()]);
        let (data, _) = send(
            &mut c,
            Command::Aprd,
            0,
            crate::esc::registers::PDI_CONTROL,
            &[0; 2],
        );
        assert_eq!(
            data,
            [0x04, 0x01],
            "digital I/O, device emulation (from the EEPROM)"
        );
        for state in [2u8, 4, 8, 1] {
            send(&mut c, Command::Apwr, 0, AL_CONTROL, &[state, 0]);
            assert_eq!(al(&mut c)[..2], [state, 0x00]);
        }
    }

    #[test]
    fn switch_cams_see_the_servo_position_after_each_tick() {
        use crate::catalog::{self, ServoOptions, SwitchesOptions, SWITCHES_INPUTS_AT};
        use crate::plant::switches::SwitchCam;
        let cam = SwitchCam {
            input: 2,
            from: 1000,
            to: 1999,
            normally_closed: false,
        };
        let switches = |axis| {
            catalog::switches(SwitchesOptions {
                serial: 9,
                axis,
                cams: vec![cam],
            })
            .unwrap()
        };
        let servo = |start_counts| {
            catalog::servo(ServoOptions {
                start_counts,
                ..ServoOptions::default()
            })
        };
        let safe_op = |c: &mut SlaveChain| {
            for i in 0..c.slaves().len() {
                c.slave_mut(i)
                    .unwrap()
                    .force_state(crate::esc::al::AlState::SafeOp);
            }
        };
        // Inside the cam; then a module pointed at a slave that is not a servo rests.
        let mut c = SlaveChain::new(vec![servo(1999), switches(0), switches(1), servo(2000)]);
        c.tick(0.001);
        let byte = |c: &SlaveChain, i: usize| {
            c.slaves()[i].memory().raw(SWITCHES_INPUTS_AT, 1).unwrap()[0]
        };
        assert_eq!(byte(&c, 1), 0, "in Init the inputs are not published");
        safe_op(&mut c);
        c.tick(0.001);
        assert_eq!(byte(&c, 1), 0b100, "from SafeOp on they are");
        assert_eq!(byte(&c, 2), 0);
        let mut c = SlaveChain::new(vec![servo(2000), switches(0)]);
        safe_op(&mut c);
        c.tick(0.001);
        assert_eq!(byte(&c, 1), 0, "one count past the cam");
    }
}
