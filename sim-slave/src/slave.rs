//! One emulated slave: its ESC memory, EEPROM and AL state, serving the datagrams that
//! pass through it, plus the side effects a real ESC has when a register is written (AL
//! control starts a state change, SII control starts an EEPROM access).

use crate::coe::{self, od::ObjectDictionary, pdo};
use crate::esc::al::AlState;
use crate::esc::al::{self, AlStatusCode};
use crate::esc::command::{self, Access, Served};
use crate::esc::datagram::Datagram;
use crate::esc::dc::{Arrival, DcUnit};
use crate::esc::memory::{Memory, RAM_BYTES};
use crate::esc::registers::{
    AL_CONTROL, AL_STATUS, AL_STATUS_CODE, DL_STATUS, FEATURES, FEATURES_DC, PROCESS_RAM, SM0,
};
use crate::esc::sii::{self, DeviceDescription, Sii};
use crate::esc::watchdog::ProcessDataWatchdog;
use crate::plant::DeviceModel;

/// SyncManager status bit 3: mailbox full.
const MAILBOX_FULL: u8 = 0x08;
/// SyncManager activate bit 1 (master): repeat request; PDI control bit 1 (slave): repeat
/// acknowledge.
const REPEAT: u8 = 0x02;

/// Register address of SyncManager `n`.
fn sm_base(n: u16) -> u16 {
    SM0 + 8 * n
}

/// Whether `[ado, ado + len)` contains `byte`.
fn covers(ado: u16, len: usize, byte: u16) -> bool {
    (ado as usize) <= byte as usize && (byte as usize) < ado as usize + len
}

/// An emulated slave.
#[derive(Clone, Debug)]
pub struct Slave {
    memory: Memory,
    sii: Sii,
    description: DeviceDescription,
    device: DeviceModel,
    /// Object dictionary of the CoE mailbox (slaves without CoE have none).
    od: Option<ObjectDictionary>,
    watchdog: ProcessDataWatchdog,
    /// The DC unit (slaves whose description has no DC have none).
    dc: Option<DcUnit>,
    /// When the frame being served passes this slave (set by the chain per frame).
    arrival: Arrival,
    /// Whether the read mailbox (SM1) holds an answer the master may ask to be repeated.
    answered: bool,
    /// The SDO server's segmented transfer, if one runs.
    sdo: coe::SdoServer,
}

impl Slave {
    /// A slave in Init with its EEPROM generated from `description`.
    pub fn new(description: DeviceDescription) -> Self {
        let sii = Sii::new(description.image());
        let (mut memory, dc) = if description.dc {
            (Memory::new(), Some(DcUnit::new(0.0, 0)))
        } else {
            let mut memory = Memory::without_dc();
            let features = memory.read_u16(FEATURES) & !(FEATURES_DC as u16);
            memory.pdi_write(FEATURES, &features.to_le_bytes());
            (memory, None)
        };
        sii.reset(&mut memory);
        Self {
            memory,
            sii,
            description,
            device: DeviceModel::None,
            od: None,
            watchdog: ProcessDataWatchdog::default(),
            dc,
            arrival: Arrival::default(),
            answered: false,
            sdo: coe::SdoServer::default(),
        }
    }

    /// The same slave with its DC clock running `drift_ppm` fast (negative: slow) and
    /// reading `local_at_zero` ns at chain time 0 (ESCs power up at different times).
    /// No effect on a slave without DC.
    pub fn with_dc_clock(mut self, drift_ppm: f64, local_at_zero: u64) -> Self {
        if self.dc.is_some() {
            self.dc = Some(DcUnit::new(drift_ppm, local_at_zero));
        }
        self
    }

    /// The same slave with its DC clock running `drift_ppm` fast (negative: slow).
    pub fn with_dc_drift_ppm(self, drift_ppm: f64) -> Self {
        self.with_dc_clock(drift_ppm, 0)
    }

    /// The DC unit, if the slave has DC.
    pub fn dc(&self) -> Option<&DcUnit> {
        self.dc.as_ref()
    }

    /// The slave's system time at chain time `t` (ns), if it has DC: what a read of
    /// 0x0910 would return if a frame passed then.
    pub fn dc_system_time(&self, t: u64) -> Option<u64> {
        self.dc.as_ref().map(|dc| dc.system_time(&self.memory, t))
    }

    /// SYNC0 pulses generated so far (0 without DC); device models latch on its change.
    pub fn sync0_events(&self) -> u64 {
        self.dc.as_ref().map_or(0, DcUnit::sync0_pulses)
    }

    /// The next frame passes this slave at these times (chain time).
    pub fn frame_arrives(&mut self, arrival: Arrival) {
        self.arrival = arrival;
    }

    /// The chain's time is now `t` (ns): the cyclic unit generates the SYNC0 pulses due.
    pub fn advance_to(&mut self, t: u64) {
        if let Some(dc) = self.dc.as_mut() {
            dc.advance(&mut self.memory, t);
        }
    }

    /// The same slave with a CoE object dictionary behind its mailbox (SM0 in, SM1 out).
    pub fn with_coe(mut self, od: ObjectDictionary) -> Self {
        self.od = Some(od);
        self
    }

    /// The object dictionary, if the slave has CoE.
    pub fn object_dictionary(&self) -> Option<&ObjectDictionary> {
        self.od.as_ref()
    }

    /// The same slave with an application behind its ESC.
    pub fn with_device(mut self, device: DeviceModel) -> Self {
        self.device = device;
        self
    }

    /// The application.
    pub fn device(&self) -> &DeviceModel {
        &self.device
    }

    /// The application, mutable (a test turns an encoder's shaft).
    pub fn device_mut(&mut self) -> &mut DeviceModel {
        &mut self.device
    }

    /// Tells the application where the axis it watches is (counts); see
    /// [`crate::chain::SlaveChain::tick`].
    pub fn couple(&mut self, position: i64) {
        self.device.on_axis_position(&mut self.memory, position);
    }

    /// Runs `dt_s` seconds of the application (device models read outputs and write inputs).
    pub fn tick(&mut self, dt_s: f64) {
        let in_op = AlState::from_bits(self.al_status()) == AlState::Op;
        if !in_op {
            self.watchdog.disarm(&mut self.memory);
        } else if self.watchdog.tick(&mut self.memory, dt_s) {
            // The master stopped sending: leave Op with the error flagged, and let the
            // application react (a drive stops its motor and faults).
            let status = u16::from(AlState::SafeOp.raw()) | al::ERROR_BIT;
            self.memory.pdi_write(AL_STATUS, &status.to_le_bytes());
            let code = AlStatusCode::SyncManagerWatchdog.raw();
            self.memory.pdi_write(AL_STATUS_CODE, &code.to_le_bytes());
            self.device.on_watchdog();
        }
        self.device.step(&mut self.memory, dt_s);
    }

    /// The device description.
    pub fn description(&self) -> &DeviceDescription {
        &self.description
    }

    /// ESC memory (for inspection in tests and by device models).
    pub fn memory(&self) -> &Memory {
        &self.memory
    }

    /// Writes process RAM from the device side (inputs a device model produces).
    pub fn write_process_ram(&mut self, address: u16, data: &[u8]) {
        self.memory.pdi_write(address, data);
    }

    /// Current AL status register.
    pub fn al_status(&self) -> u16 {
        self.memory.read_u16(AL_STATUS)
    }

    /// Current AL status code.
    pub fn al_status_code(&self) -> AlStatusCode {
        AlStatusCode::from_raw(self.memory.read_u16(AL_STATUS_CODE))
    }

    /// Sets DL status (0x0110) for the ports that are wired: link and communication on a
    /// wired port, loop closed on an open one; PDI operational (the EEPROM was loaded).
    pub fn set_ports(&mut self, wired: [bool; 4]) {
        let mut v: u16 = 1; // PDI operational
        for (port, &on) in wired.iter().enumerate() {
            if on {
                v |= 1 << (4 + port); // physical link
                v |= 1 << (9 + 2 * port); // communication established
            } else {
                v |= 1 << (8 + 2 * port); // loop closed
            }
        }
        self.memory.pdi_write(DL_STATUS, &v.to_le_bytes());
    }

    /// Serves one datagram and applies the side effects of what it wrote.
    pub fn serve(&mut self, d: &mut Datagram<&mut [u8]>) -> Served {
        match command::address(&self.memory, d) {
            // Most datagrams of a cyclic frame are for other slaves: nothing to do.
            Access::None => Served::Passed,
            Access::Logical => self.serve_logical(d),
            access => self.serve_physical(d, access),
        }
    }

    /// Process data (the hot path): a logical write lands in the SyncManager areas the
    /// FMMUs map; nothing else reacts to it.
    fn serve_logical(&mut self, d: &mut Datagram<&mut [u8]>) -> Served {
        let served = command::apply(&mut self.memory, d, Access::Logical);
        let written = matches!(served, Served::Written | Served::ReadWritten);
        if written && ProcessDataWatchdog::triggered_by(&self.memory, PROCESS_RAM, RAM_BYTES) {
            self.watchdog.trigger(&mut self.memory);
        }
        served
    }

    /// Serves a register or RAM access by address (not through the FMMUs). Kept out of
    /// [`Slave::serve`] so that passing a datagram on stays a few instructions.
    #[inline(never)]
    fn serve_physical(&mut self, d: &mut Datagram<&mut [u8]>, access: Access) -> Served {
        let ado = d.ado();
        let len = d.data_len();
        if let Some(dc) = self.dc.as_ref() {
            dc.before_access(&mut self.memory, ado, len, &self.arrival);
        }
        let sm1_was_active = self.sync_manager(1).2;
        // Mailbox mode (ESC datasheet section I, 8.2): an empty read mailbox cannot be
        // read — the access fails and the working counter stays. Keep what the frame
        // carried so that a refused read leaves it as it came.
        let refused_read = self.read_mailbox_empty(ado, len);
        let before = refused_read.then(|| (d.data().to_vec(), d.wkc()));
        let served = command::apply(&mut self.memory, d, access);
        if let Some((data, wkc)) = before {
            if matches!(served, Served::Read | Served::ReadWritten) {
                d.data_mut().copy_from_slice(&data);
                d.set_wkc(wkc);
                return Served::Passed;
            }
        }
        let written = matches!(served, Served::Written | Served::ReadWritten);
        // Process data written by address lands where it says.
        if written && ProcessDataWatchdog::triggered_by(&self.memory, ado, len) {
            self.watchdog.trigger(&mut self.memory);
        }
        if let (Some(dc), true) = (self.dc.as_mut(), written) {
            dc.after_write(&mut self.memory, ado, len, &self.arrival);
        }
        if let (Some(dc), Served::Read | Served::ReadWritten) = (self.dc.as_mut(), served) {
            dc.after_read(&mut self.memory, ado, len);
        }
        if written {
            let touched = |reg: u16, w: usize| {
                (ado as usize) < reg as usize + w && (ado as usize + len) > reg as usize
            };
            if touched(AL_CONTROL, 2) {
                self.on_al_control();
            }
            if sii::touches_control(ado, len) {
                self.sii.on_control_write(&mut self.memory);
            }
            if touched(SM0, 8 * 8) {
                self.on_sync_manager_write(sm1_was_active);
            }
            let (start, length, active) = self.sync_manager(0);
            if active && length > 0 && covers(ado, len, start + length - 1) {
                self.on_mailbox_write(start, length);
            }
        }
        if matches!(served, Served::Read | Served::ReadWritten) {
            let (start, length, active) = self.sync_manager(1);
            if active && length > 0 && covers(ado, len, start + length - 1) {
                // The master read the last byte: the mailbox is empty again.
                let status = self.memory.read_u16(sm_base(1) + 4) & !(u16::from(MAILBOX_FULL) << 8);
                self.memory.pdi_write(sm_base(1) + 4, &status.to_le_bytes());
            }
        }
        served
    }

    /// Whether `[ado, ado + len)` lies in the read mailbox (SM1) while it is enabled and
    /// empty.
    fn read_mailbox_empty(&self, ado: u16, len: usize) -> bool {
        let (start, length, active) = self.sync_manager(1);
        let full = self.byte(sm_base(1) + 5) & MAILBOX_FULL != 0;
        active
            && !full
            && length > 1
            && ado >= start
            && ado as usize + len <= start as usize + length as usize
    }

    fn byte(&self, address: u16) -> u8 {
        self.memory
            .raw(address, 1)
            .and_then(|b| b.first().copied())
            .unwrap_or(0)
    }

    /// The master wrote SyncManager registers. A disabled SyncManager loses its buffer
    /// state (datasheet section I, 8.7: the state is reset; a mailbox is empty again).
    /// On the read mailbox, a toggled repeat request (activate bit 1) makes the
    /// application put its last answer back and toggle the repeat acknowledge (PDI
    /// control bit 1) — how a master recovers an answer whose frame was lost (section I,
    /// 8.6, Figure 26). Enabling the mailbox starts with request and acknowledge equal.
    fn on_sync_manager_write(&mut self, sm1_was_active: bool) {
        for n in 0..8 {
            let base = sm_base(n);
            if self.byte(base + 6) & 0x01 == 0 {
                let status = self.byte(base + 5) & !MAILBOX_FULL;
                self.memory.pdi_write(base + 5, &[status]);
                if n == 1 {
                    self.answered = false;
                }
            }
        }
        let base = sm_base(1);
        let (request, pdi) = (self.byte(base + 6), self.byte(base + 7));
        if request & 0x01 == 0 || request & REPEAT == pdi & REPEAT {
            return;
        }
        if sm1_was_active && self.answered {
            let status = self.byte(base + 5) | MAILBOX_FULL;
            self.memory.pdi_write(base + 5, &[status]);
        }
        self.memory
            .pdi_write(base + 7, &[(pdi & !REPEAT) | (request & REPEAT)]);
    }

    /// SyncManager `n` as the master configured it: (start, length, enabled).
    fn sync_manager(&self, n: u16) -> (u16, u16, bool) {
        let base = sm_base(n);
        let start = self.memory.read_u16(base);
        let length = self.memory.read_u16(base + 2);
        let active = self.memory.read_u16(base + 6) & 0x01 != 0;
        (start, length, active)
    }

    /// A request arrived in the write mailbox (SM0): serve it, put the answer in the read
    /// mailbox (SM1) and mark that full.
    fn on_mailbox_write(&mut self, start: u16, length: u16) {
        let Some(od) = self.od.as_mut() else { return };
        let mut request = vec![0u8; length as usize];
        self.memory.ecat_read(start, &mut request, false);
        let (out_start, out_len, out_active) = {
            let base = sm_base(1);
            (
                self.memory.read_u16(base),
                self.memory.read_u16(base + 2),
                self.memory.read_u16(base + 6) & 0x01 != 0,
            )
        };
        // The drive's objects are live: its values in before, what was written out after.
        self.device.publish_objects(od);
        let response = coe::serve(od, &mut self.sdo, &request, usize::from(out_len));
        self.device.take_objects(od);
        let Some(response) = response else {
            return;
        };
        if !out_active || response.len() > out_len as usize {
            return;
        }
        let mut area = vec![0u8; out_len as usize];
        if let Some(dst) = area.get_mut(..response.len()) {
            dst.copy_from_slice(&response);
        }
        self.memory.pdi_write(out_start, &area);
        let status = self.memory.read_u16(sm_base(1) + 4) | (u16::from(MAILBOX_FULL) << 8);
        self.memory.pdi_write(sm_base(1) + 4, &status.to_le_bytes());
        self.answered = true;
    }

    fn on_al_control(&mut self) {
        let control = self.memory.read_u16(AL_CONTROL);
        let status = self.memory.read_u16(AL_STATUS);
        let code = AlStatusCode::from_raw(self.memory.read_u16(AL_STATUS_CODE));
        // PreOp → SafeOp: the process data the master set up must be what the mapped
        // PDOs say (SM2 outputs, SM3 inputs), as a real device checks.
        let layout = self
            .od
            .as_ref()
            .and_then(|od| od.pdo_rules().map(|rules| pdo::layout(od, rules)));
        let (sm2, sm3) = (self.sync_manager(2), self.sync_manager(3));
        let out = al::on_control(status, code, control, false, |from, to| {
            match (&layout, from, to) {
                (Some(layout), AlState::PreOp, AlState::SafeOp) => {
                    let layout = layout
                        .as_ref()
                        .map_err(|_| AlStatusCode::InvalidOutputConfig)?;
                    if usize::from(sm2.1) != layout.output_bytes() || !sm2.2 {
                        return Err(AlStatusCode::InvalidOutputConfig);
                    }
                    if usize::from(sm3.1) != layout.input_bytes() || !sm3.2 {
                        return Err(AlStatusCode::InvalidInputConfig);
                    }
                    Ok(())
                }
                _ => Ok(()),
            }
        });
        let before = AlState::from_bits(status);
        let after = AlState::from_bits(out.status);
        if let (AlState::PreOp, AlState::SafeOp, Some(Ok(layout))) = (before, after, layout) {
            self.device.configure_pdo(layout);
        }
        if let Some(od) = self.od.as_mut() {
            od.set_pre_op(after == AlState::PreOp);
        }
        self.memory.pdi_write(AL_STATUS, &out.status.to_le_bytes());
        self.memory
            .pdi_write(AL_STATUS_CODE, &out.code.raw().to_le_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::{self, ServoOptions, MAILBOX_IN_AT, MAILBOX_OUT_AT};
    use crate::esc::datagram::Command;

    /// Serves one FPxx datagram to station 0 (the reset address); returns (WKC, data).
    fn fp(slave: &mut Slave, cmd: Command, ado: u16, data: &[u8]) -> (u16, Vec<u8>) {
        let mut buf = vec![0u8; 12 + data.len()];
        let mut d = Datagram::new_unchecked(&mut buf[..]);
        d.set_command(cmd);
        d.set_adp(0);
        d.set_ado(ado);
        d.set_len(data.len(), false, false);
        d.data_mut().copy_from_slice(data);
        slave.serve(&mut d);
        (d.wkc(), d.data().to_vec())
    }

    /// A servo with its mailbox SyncManagers set up as a master does (one 16-byte write).
    fn servo_with_mailbox() -> Slave {
        let mut s = catalog::servo(ServoOptions::default());
        let mut sms = Vec::new();
        for (at, control) in [(MAILBOX_OUT_AT, 0x26u8), (MAILBOX_IN_AT, 0x22)] {
            sms.extend(at.to_le_bytes());
            sms.extend(128u16.to_le_bytes());
            sms.extend([control, 0, 0x01, 0]);
        }
        assert_eq!(fp(&mut s, Command::Fpwr, SM0, &sms).0, 1);
        s
    }

    /// An SDO upload request of 0x1018:01 in a 128-byte mailbox.
    fn upload_1018_01(counter: u8) -> Vec<u8> {
        let mut m = vec![0u8; 128];
        m[0] = 10;
        m[5] = coe::MAILBOX_TYPE_COE | (counter << 4);
        m[6..8].copy_from_slice(&(coe::COE_SDO_REQUEST << 12).to_le_bytes());
        m[8..12].copy_from_slice(&[0x40, 0x18, 0x10, 0x01]);
        m
    }

    fn full(s: &Slave) -> bool {
        s.byte(sm_base(1) + 5) & MAILBOX_FULL != 0
    }

    #[test]
    fn an_empty_read_mailbox_cannot_be_read() {
        let mut s = servo_with_mailbox();
        let (wkc, data) = fp(&mut s, Command::Fprd, MAILBOX_IN_AT, &[0xAA; 128]);
        assert_eq!(wkc, 0, "read of an empty mailbox fails");
        assert!(data.iter().all(|&b| b == 0xAA), "the frame keeps its data");
        assert_eq!(
            fp(&mut s, Command::Fpwr, MAILBOX_OUT_AT, &upload_1018_01(1)).0,
            1
        );
        assert!(full(&s));
        let (wkc, answer) = fp(&mut s, Command::Fprd, MAILBOX_IN_AT, &[0; 128]);
        assert_eq!(wkc, 1);
        assert_eq!(&answer[8..12], &[0x43, 0x18, 0x10, 0x01]);
        assert!(!full(&s), "read to the last byte empties it");
        assert_eq!(fp(&mut s, Command::Fprd, MAILBOX_IN_AT, &[0; 128]).0, 0);
        // The registers stay readable, and so does anything outside the mailbox.
        assert_eq!(fp(&mut s, Command::Fprd, sm_base(1) + 5, &[0; 2]).0, 1);
    }

    #[test]
    fn a_repeat_request_puts_the_last_answer_back() {
        let mut s = servo_with_mailbox();
        // No answer yet: a repeat request is acknowledged but there is nothing to read.
        assert_eq!(fp(&mut s, Command::Fpwr, sm_base(1) + 6, &[0x03]).0, 1);
        assert_eq!(s.byte(sm_base(1) + 7) & REPEAT, REPEAT);
        assert!(!full(&s));
        fp(&mut s, Command::Fpwr, MAILBOX_OUT_AT, &upload_1018_01(2));
        let (_, first) = fp(&mut s, Command::Fprd, MAILBOX_IN_AT, &[0; 128]);
        // The frame carrying the answer was lost: the master toggles the request bit
        // (SOEM writes status + activate as one word; the status byte is ignored).
        assert_eq!(
            fp(&mut s, Command::Fpwr, sm_base(1) + 5, &[0x00, 0x01]).0,
            1
        );
        assert_eq!(
            s.byte(sm_base(1) + 7) & REPEAT,
            0,
            "acknowledge follows the request"
        );
        assert!(full(&s), "the answer is back");
        let (wkc, again) = fp(&mut s, Command::Fprd, MAILBOX_IN_AT, &[0; 128]);
        assert_eq!((wkc, &again), (1, &first));
        // Writing the request bit unchanged repeats nothing.
        fp(&mut s, Command::Fpwr, sm_base(1) + 6, &[0x01]);
        assert!(!full(&s));
    }

    #[test]
    fn status_is_the_escs_and_disabling_empties_the_mailbox() {
        let mut s = servo_with_mailbox();
        fp(&mut s, Command::Fpwr, MAILBOX_OUT_AT, &upload_1018_01(3));
        assert!(full(&s));
        fp(&mut s, Command::Fpwr, sm_base(1) + 5, &[0x00]);
        assert!(full(&s), "the status byte is read-only from EtherCAT");
        // A master that resets every SyncManager (SOEM: BWR of zeros over 0x0800).
        fp(&mut s, Command::Fpwr, SM0, &[0; 32]);
        assert!(!full(&s), "a disabled SyncManager is reset");
        // Enabled again with the repeat bit set: a fresh start, not a repeat.
        fp(&mut s, Command::Fpwr, SM0, &{
            let mut sms = [0u8; 16];
            sms[8..10].copy_from_slice(&MAILBOX_IN_AT.to_le_bytes());
            sms[10..12].copy_from_slice(&128u16.to_le_bytes());
            sms[12] = 0x22;
            sms[14] = 0x03;
            sms
        });
        assert!(!full(&s));
        assert_eq!(s.byte(sm_base(1) + 7) & REPEAT, REPEAT);
    }
}
