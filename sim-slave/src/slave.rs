//! One emulated slave: its ESC memory, EEPROM and AL state, serving the datagrams that
//! pass through it, plus the side effects a real ESC has when a register is written (AL
//! control starts a state change, SII control starts an EEPROM access, a SyncManager's
//! last byte completes its buffer) and the firmware behind it (the AL transitions take
//! time and check what a device checks).

use crate::coe::{self, od::ObjectDictionary, pdo};
use crate::esc::al::{self, AlState, AlStatusCode, Firmware, SAFEOP_OP_TIMEOUT_NS};
use crate::esc::command::{self, Access, Served};
use crate::esc::datagram::Datagram;
use crate::esc::dc::{Arrival, DcUnit};
use crate::esc::fmmu;
use crate::esc::memory::{Memory, RAM_BYTES};
use crate::esc::registers::{
    AL_CONTROL, AL_STATUS, AL_STATUS_CODE, DC_ACTIVATION, DL_STATUS, ESC_CONFIG, FEATURES,
    FEATURES_DC, PROCESS_RAM, SM0,
};
use crate::esc::sii::{self, DeviceDescription, Sii};
use crate::esc::sync_manager::{self as sm, status, Kind, SyncManager};
use crate::esc::watchdog::ProcessDataWatchdog;
use crate::plant::{DeviceModel, Exchange};

/// ESC configuration (0x0141) bit 0: device emulation, the ESC itself copies AL control
/// to AL status (ESC datasheet section II, 0x0141; simple I/O terminals without firmware).
const DEVICE_EMULATION: u8 = 0x01;
/// DC activation (0x0981) bits: cyclic operation, SYNC0, SYNC1.
const DC_CYCLIC: u8 = 0x01;
const DC_SYNC0: u8 = 0x02;
const DC_SYNC1: u8 = 0x04;
/// Object 0x1C32, SM output parameter (ETG.1020).
pub const SM_OUTPUT_PARAMETER: u16 = 0x1C32;
/// Object 0x10F1, error settings (sub 2: sync error counter limit).
pub const ERROR_SETTINGS: u16 = 0x10F1;
/// Smallest mailbox the firmware accepts (mailbox header, CoE header and an expedited
/// SDO: the slave stack code's MIN_MBX_SIZE is 34 bytes).
const MIN_MAILBOX_BYTES: u16 = 34;

/// A transition the firmware is working on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Pending {
    from: AlState,
    to: AlState,
    /// Chain time it completes (if what it waits for is there).
    due: u64,
    /// Chain time it gives up (SafeOp → Op waiting for outputs or SYNC0).
    deadline: u64,
}

/// The application's copy of a buffered output SyncManager (3-buffer mode): the last
/// buffer the master completed. The ESC memory holds the buffer being written.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
struct OutputBuffer {
    /// The SyncManager it belongs to.
    sm: u16,
    /// Its start and length when it was set up.
    start: u16,
    /// Completed contents.
    data: Vec<u8>,
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
    /// Whether the read mailbox holds an answer the master may ask to be repeated.
    answered: bool,
    /// The SDO server's segmented transfer, if one runs.
    sdo: coe::SdoServer,
    /// The counter of the last mailbox request served (ETG.1000.6 Table 29): a request
    /// with the same non-zero counter is a repeat of it and is discarded.
    mailbox_counter: u8,
    /// An answer the firmware is still working on: when it is due (chain time) and the
    /// SM1 area it will write ([`Firmware::mailbox_response_ns`]).
    answer_due: Option<(u64, Vec<u8>)>,
    /// Whether the ESC loaded its EEPROM's configuration area (DL status bit 0).
    eeprom_loaded: bool,
    /// The ports wired (DL status), as the chain last set them.
    wired: [bool; 4],
    /// What the firmware requires of transitions.
    firmware: Firmware,
    /// The transition in progress.
    pending: Option<Pending>,
    /// The chain's time as last seen (frames and `advance_to`).
    now: u64,
    /// The output SyncManager completed a buffer since the device entered SafeOp.
    outputs_received: bool,
    /// The device runs synchronised to SYNC0 (decided at PreOp → SafeOp from 0x0981).
    dc_mode: bool,
    /// SYNC0 pulses counted when SafeOp was entered.
    sync0_at_safeop: u64,
    /// Completed output buffers the application reads (3-buffer mode).
    outputs: Vec<OutputBuffer>,
    /// What the firmware counts of the outputs against SYNC0 (0x1C32).
    sync: SyncCounters,
}

/// The SyncManager output parameters (object 0x1C32) a DC-synchronous device keeps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SyncCounters {
    /// SYNC0 edges seen so far.
    sync0_seen: u64,
    /// Output buffers completed since the last SYNC0 edge.
    buffers_since_sync0: u32,
    /// 0x1C32:0B SM event missed counter (+3 per SYNC0 without outputs, −1 per buffer).
    pub sm_event_missed: u16,
    /// 0x1C32:0C cycle time too small: a second output buffer within one SYNC0 period
    /// (the first was overwritten before the device took it).
    pub cycle_time_too_small: u16,
    /// 0x1C32:20 sync error: the SM event missed counter reached the limit.
    pub sync_error: bool,
}

impl Slave {
    /// A slave in Init with its EEPROM generated from `description`.
    pub fn new(description: DeviceDescription) -> Self {
        let mut sii = Sii::new(description.image());
        let (mut memory, dc) = if description.dc {
            (Memory::new(), Some(DcUnit::new(0.0, 0)))
        } else {
            let mut memory = Memory::without_dc();
            let features = memory.read_u16(FEATURES) & !(FEATURES_DC as u16);
            memory.pdi_write(FEATURES, &features.to_le_bytes());
            (memory, None)
        };
        let eeprom_loaded = sii.reset(&mut memory);
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
            mailbox_counter: 0,
            answer_due: None,
            eeprom_loaded,
            wired: [false; 4],
            firmware: Firmware::SIMPLE,
            pending: None,
            now: 0,
            outputs_received: false,
            dc_mode: false,
            sync0_at_safeop: 0,
            outputs: Vec::new(),
            sync: SyncCounters::default(),
        }
    }

    /// What the firmware counted of the outputs against SYNC0 (object 0x1C32).
    pub fn sync_counters(&self) -> &SyncCounters {
        &self.sync
    }

    /// The same slave with this firmware behind its ESC (transition times and checks).
    pub fn with_firmware(mut self, firmware: Firmware) -> Self {
        self.firmware = firmware;
        self
    }

    /// The firmware's settings.
    pub fn firmware(&self) -> &Firmware {
        &self.firmware
    }

    /// What the application reads of buffered output SyncManager `n`: the last buffer the
    /// master completed (`None` when `n` is not an enabled buffered output SyncManager).
    pub fn application_outputs(&self, n: u16) -> Option<&[u8]> {
        self.outputs
            .iter()
            .find(|b| b.sm == n)
            .map(|b| b.data.as_slice())
    }

    /// The same slave with word `addr` of its EEPROM programmed to `value` (the
    /// configuration area's checksum follows, as a programming tool writes it), then
    /// power-cycled so the ESC loads it: e.g. the station alias (word 4) or PDI control
    /// (word 0).
    pub fn with_eeprom_word(mut self, addr: usize, value: u16) -> Self {
        self.sii.program(addr, value);
        self.eeprom_loaded = self.sii.reset(&mut self.memory);
        self.set_ports(self.wired);
        self
    }

    /// The EEPROM interface.
    pub fn sii(&self) -> &Sii {
        &self.sii
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

    /// The chain's time is now `t` (ns): the cyclic unit generates the SYNC0 pulses due,
    /// an EEPROM access due completes, a transition due completes (or gives up), the
    /// process-data watchdog expires if the master has been silent for its time.
    pub fn advance_to(&mut self, t: u64) {
        self.now = self.now.max(t);
        if let Some(dc) = self.dc.as_mut() {
            dc.advance(&mut self.memory, t);
        }
        let edges = self.sync0_events().saturating_sub(self.sync.sync0_seen);
        if edges > 0 {
            self.sync.sync0_seen = self.sync0_events();
            if self.dc_mode {
                self.on_sync0(edges);
            }
        }
        if let Some(loaded) = self.sii.advance(&mut self.memory, t) {
            self.eeprom_loaded = loaded;
            self.set_ports(self.wired);
        }
        self.run_transition(t);
        self.post_answer();
        let in_op = AlState::from_bits(self.al_status()) == AlState::Op;
        if !in_op {
            self.watchdog.disarm(&mut self.memory, t);
        } else if self.watchdog.check(&mut self.memory, t) {
            // The master stopped sending: leave Op with the error flagged, and let the
            // application react (a drive stops its motor and faults).
            self.set_al(
                u16::from(AlState::SafeOp.raw()) | al::ERROR_BIT,
                AlStatusCode::SyncManagerWatchdog,
            );
            self.device.on_watchdog();
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

    /// The object dictionary, to add objects a device of a test has (a vendor's long
    /// strings or tables), if the slave has CoE.
    pub fn object_dictionary_mut(&mut self) -> Option<&mut ObjectDictionary> {
        self.od.as_mut()
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
        let exchange = Exchange::in_state(AlState::from_bits(self.al_status()));
        self.device
            .on_axis_position(&mut self.memory, position, exchange);
    }

    /// Runs `dt_s` seconds of the application (device models read outputs and write
    /// inputs). In 3-buffer mode it reads the last buffer the master completed, not
    /// what a master is half-way through writing; reading clears the SyncManager's
    /// write event, writing the inputs clears its read event and names the new buffer.
    pub fn tick(&mut self, dt_s: f64) {
        let state = AlState::from_bits(self.al_status());
        for b in &mut self.outputs {
            swap_buffer(&mut self.memory, b);
        }
        let exchange = Exchange::in_state(state);
        match &mut self.device {
            // A drive takes its outputs at SYNC0 or when the frame wrote them, not here;
            // its inputs are valid from SafeOp on (ETG.1000.6 §6.4.1), not before.
            DeviceModel::Servo(drive) => {
                drive.run(dt_s);
                if exchange.inputs {
                    drive.publish_inputs(&mut self.memory);
                }
            }
            device => device.step(&mut self.memory, dt_s, exchange),
        }
        for b in &mut self.outputs {
            swap_buffer(&mut self.memory, b);
        }
        for n in 0..sm::COUNT {
            let s = SyncManager::read_from(&self.memory, n);
            if !s.enabled() {
                continue;
            }
            match s.kind() {
                Kind::BufferedWrite => {
                    sm::set_status(&mut self.memory, n, s.status & !status::INTERRUPT_WRITE);
                }
                Kind::BufferedRead => {
                    let next = SyncManager::next_buffer(s.status);
                    let kept = s.status & !(status::INTERRUPT_READ | status::BUFFER_MASK);
                    sm::set_status(&mut self.memory, n, kept | next);
                }
                _ => {}
            }
        }
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

    /// The device's application leaves Op on its own for SafeOp with the error flag and
    /// `code` (a local error, ETG.1000.6 §6.4.1: e.g. a drive's own sync monitoring).
    /// Its SyncManagers stay active — it takes outputs (as the safe state: a drive is
    /// disabled) and gives inputs — so the master's LRW working counter does not change.
    /// Nothing happens outside Op.
    pub fn local_error(&mut self, code: AlStatusCode) {
        if AlState::from_bits(self.al_status()) == AlState::Op {
            self.set_al(u16::from(AlState::SafeOp.raw()) | al::ERROR_BIT, code);
        }
    }

    /// Sets DL status (0x0110) for the ports that are wired: link and communication on a
    /// wired port, loop closed on an open one; bit 0, PDI operational, when the EEPROM's
    /// configuration area was loaded.
    pub fn set_ports(&mut self, wired: [bool; 4]) {
        self.wired = wired;
        let mut v: u16 = u16::from(self.eeprom_loaded);
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
    /// FMMUs map; a write that reaches an output buffer's last byte completes it.
    fn serve_logical(&mut self, d: &mut Datagram<&mut [u8]>) -> Served {
        let served = command::apply(&mut self.memory, d, Access::Logical);
        if matches!(served, Served::Written | Served::ReadWritten) {
            self.now = self.now.max(self.arrival.port0);
            // Any write into a SyncManager with the trigger bit restarts the watchdog.
            if ProcessDataWatchdog::triggered_by(&self.memory, PROCESS_RAM, RAM_BYTES) {
                self.watchdog.trigger(&mut self.memory, self.now);
            }
            let (addr, len) = (d.logical_address(), d.data_len());
            for n in 0..sm::COUNT {
                let s = SyncManager::read_from(&self.memory, n);
                if s.enabled()
                    && s.kind() == Kind::BufferedWrite
                    && s.last()
                        .is_some_and(|last| fmmu::writes_byte(&self.memory, addr, len, last))
                {
                    self.buffer_written(n, s);
                }
            }
        }
        if matches!(served, Served::Read | Served::ReadWritten) {
            let (addr, len) = (d.logical_address(), d.data_len());
            for n in 0..sm::COUNT {
                let s = SyncManager::read_from(&self.memory, n);
                if s.enabled()
                    && s.kind() == Kind::BufferedRead
                    && s.last()
                        .is_some_and(|last| fmmu::reads_byte(&self.memory, addr, len, last))
                {
                    sm::set_status(&mut self.memory, n, s.status | status::INTERRUPT_READ);
                }
            }
        }
        served
    }

    /// The master completed a buffer of output SyncManager `n`: the application gets it,
    /// the status shows the write event and the buffer's number, the watchdog restarts.
    fn buffer_written(&mut self, n: u16, s: SyncManager) {
        let next = SyncManager::next_buffer(s.status);
        let kept = s.status & !status::BUFFER_MASK;
        sm::set_status(&mut self.memory, n, kept | next | status::INTERRUPT_WRITE);
        if let Some(b) = self.outputs.iter_mut().find(|b| b.sm == n) {
            if let Some(area) = self.memory.raw(b.start, b.data.len()) {
                b.data.copy_from_slice(area);
            }
        }
        self.outputs_received = true;
        let in_op = AlState::from_bits(self.al_status()) == AlState::Op;
        if self.dc_mode {
            // DC: the device takes the outputs at its next SYNC0 edge; a second buffer
            // before that edge overwrites the first, which is never taken.
            self.sync.buffers_since_sync0 = self.sync.buffers_since_sync0.saturating_add(1);
            self.sync.sm_event_missed = self.sync.sm_event_missed.saturating_sub(1);
            if self.sync.buffers_since_sync0 >= 2 && in_op {
                self.sync.cycle_time_too_small = self.sync.cycle_time_too_small.wrapping_add(1);
                if let Some(r) = self.device.record_mut() {
                    r.doubled();
                }
            }
        } else if in_op {
            // Free run (SM-synchronous): the frame that completed the buffer is the event.
            self.device.take_outputs(&self.memory);
        }
    }

    /// Serves a register or RAM access by address (not through the FMMUs). Kept out of
    /// [`Slave::serve`] so that passing a datagram on stays a few instructions.
    #[inline(never)]
    fn serve_physical(&mut self, d: &mut Datagram<&mut [u8]>, access: Access) -> Served {
        let ado = d.ado();
        let len = d.data_len();
        self.now = self.now.max(self.arrival.port0);
        if let Some(dc) = self.dc.as_ref() {
            dc.before_access(&mut self.memory, ado, len, &self.arrival);
        }
        let read_mailbox_was_active = self.mailbox(Kind::MailboxRead).is_some();
        let enabled_before = self.enabled_mask();
        // Mailbox mode (ESC datasheet section I, 8.2): an empty read mailbox cannot be
        // read, a full write mailbox cannot be written — the access fails and the working
        // counter stays. Keep what the frame carried so that a refused access leaves it
        // (and the memory) as it came.
        let refused = self.mailbox_refuses(ado, len, access);
        let before = refused.then(|| (d.data().to_vec(), d.wkc()));
        let kept = refused.then(|| self.mailbox_bytes(ado, len));
        let served = command::apply(&mut self.memory, d, access);
        if let (Some((data, wkc)), Some(kept)) = (before, kept) {
            d.data_mut().copy_from_slice(&data);
            d.set_wkc(wkc);
            if let Some((at, bytes)) = kept {
                self.memory.pdi_write(at, &bytes);
            }
            return Served::Passed;
        }
        let written = matches!(served, Served::Written | Served::ReadWritten);
        let read = matches!(served, Served::Read | Served::ReadWritten);
        if written && ProcessDataWatchdog::triggered_by(&self.memory, ado, len) {
            self.watchdog.trigger(&mut self.memory, self.now);
        }
        if let (Some(dc), true) = (self.dc.as_mut(), written) {
            dc.after_write(&mut self.memory, ado, len, &self.arrival);
        }
        if let (Some(dc), true) = (self.dc.as_mut(), read) {
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
                self.sii
                    .on_control_write(&mut self.memory, self.arrival.port0);
            }
            if touched(SM0, usize::from(sm::COUNT * sm::SIZE)) {
                self.on_sync_manager_write(read_mailbox_was_active, enabled_before);
            }
            // Process data written by address lands where it says.
            for n in 0..sm::COUNT {
                let s = SyncManager::read_from(&self.memory, n);
                if !s.enabled() || !s.completed_by(ado, len) {
                    continue;
                }
                match s.kind() {
                    Kind::BufferedWrite => self.buffer_written(n, s),
                    Kind::MailboxWrite => {
                        sm::set_status(&mut self.memory, n, s.status | status::MAILBOX_FULL);
                        self.on_mailbox_write(n, s);
                    }
                    _ => {}
                }
            }
        }
        if read {
            let mut emptied = false;
            for n in 0..sm::COUNT {
                let s = SyncManager::read_from(&self.memory, n);
                if !s.enabled() || !s.completed_by(ado, len) {
                    continue;
                }
                match s.kind() {
                    // The master read the last byte: the mailbox is empty again.
                    Kind::MailboxRead => {
                        sm::set_status(&mut self.memory, n, s.status & !status::MAILBOX_FULL);
                        emptied = true;
                    }
                    Kind::BufferedRead => {
                        sm::set_status(&mut self.memory, n, s.status | status::INTERRUPT_READ);
                    }
                    _ => {}
                }
            }
            // A request that waited for the answer before it to be read is served now.
            let waiting = emptied
                .then(|| self.mailbox(Kind::MailboxWrite))
                .flatten()
                .filter(|(_, s)| s.status & status::MAILBOX_FULL != 0);
            if let Some((n, s)) = waiting {
                self.on_mailbox_write(n, s);
            }
        }
        served
    }

    /// `edges` SYNC0 pulses came (more than one when the chain caught up after a stall).
    /// In Op the device takes the last completed output buffer at the first; an edge with
    /// no buffer since the previous one is a missed setpoint (0x1C32:0B +3, the drive's
    /// record); at the 0x10F1:02 limit it leaves Op with a sync error (0x001A) and the
    /// drive faults (its fault reaction for a lost sync: 0x8700, sync controller).
    fn on_sync0(&mut self, edges: u64) {
        let in_op = AlState::from_bits(self.al_status()) == AlState::Op;
        let counting = in_op && self.outputs_received;
        let mut missed = 0u64;
        if self.sync.buffers_since_sync0 == 0 {
            missed += 1;
        } else if in_op {
            for b in &mut self.outputs {
                swap_buffer(&mut self.memory, b);
            }
            self.device.take_outputs(&self.memory);
            for b in &mut self.outputs {
                swap_buffer(&mut self.memory, b);
            }
        }
        // Every further edge of a catch-up had no buffer before it.
        missed += edges - 1;
        self.sync.buffers_since_sync0 = 0;
        if !counting || missed == 0 {
            return;
        }
        if let Some(r) = self.device.record_mut() {
            r.missed(missed.min(u64::from(u32::MAX)) as u32);
        }
        let limit = self.firmware.sync_error_limit;
        for _ in 0..missed.min(u64::from(limit)) {
            if self.sync.sm_event_missed <= limit {
                self.sync.sm_event_missed = self.sync.sm_event_missed.saturating_add(3);
            }
        }
        if self.sync.sm_event_missed >= limit {
            self.sync.sync_error = true;
            self.set_al(
                u16::from(AlState::SafeOp.raw()) | al::ERROR_BIT,
                AlStatusCode::SyncError,
            );
            self.device.on_watchdog();
        }
    }

    /// Leaving Op: the outputs are no longer taken; the device gets its safe state, all
    /// outputs zero (a drive: controlword 0, disable voltage).
    fn take_safe_outputs(&mut self) {
        let Some(b) = self.outputs.first() else {
            return;
        };
        let (start, len) = (b.start, b.data.len());
        let Some(kept) = self.memory.raw(start, len).map(<[u8]>::to_vec) else {
            return;
        };
        self.memory.pdi_write(start, &vec![0; len]);
        self.device.take_outputs(&self.memory);
        self.memory.pdi_write(start, &kept);
    }

    /// Bit n set when SyncManager n is enabled.
    fn enabled_mask(&self) -> u8 {
        (0..sm::COUNT)
            .filter(|&n| SyncManager::read_from(&self.memory, n).enabled())
            .fold(0, |m, n| m | (1 << n))
    }

    /// The first enabled SyncManager of this kind: (number, registers).
    fn mailbox(&self, kind: Kind) -> Option<(u16, SyncManager)> {
        (0..sm::COUNT)
            .map(|n| (n, SyncManager::read_from(&self.memory, n)))
            .find(|(_, s)| s.enabled() && s.kind() == kind)
    }

    /// Whether the access is refused by a mailbox: a read inside an empty read mailbox,
    /// a write inside a full write mailbox.
    fn mailbox_refuses(&self, ado: u16, len: usize, access: Access) -> bool {
        let reads = matches!(
            access,
            Access::Read { .. } | Access::ReadWrite | Access::BroadcastReadWrite
        );
        let writes = matches!(
            access,
            Access::Write | Access::ReadWrite | Access::BroadcastReadWrite
        );
        (0..sm::COUNT).any(|n| {
            let s = SyncManager::read_from(&self.memory, n);
            let full = s.status & status::MAILBOX_FULL != 0;
            s.enabled()
                && s.overlaps(ado, len)
                && match s.kind() {
                    Kind::MailboxRead => reads && !full,
                    Kind::MailboxWrite => writes && full,
                    _ => false,
                }
        })
    }

    /// The memory a refused access would touch, to put back: (address, bytes).
    fn mailbox_bytes(&self, ado: u16, len: usize) -> Option<(u16, Vec<u8>)> {
        let len = len.min(usize::from(u16::MAX - ado) + 1);
        self.memory.raw(ado, len).map(|b| (ado, b.to_vec()))
    }

    fn byte(&self, address: u16) -> u8 {
        self.memory
            .raw(address, 1)
            .and_then(|b| b.first().copied())
            .unwrap_or(0)
    }

    /// The master wrote SyncManager registers. A disabled SyncManager loses its buffer
    /// state (datasheet section I, 8.7: the state is reset; a mailbox is empty again, a
    /// buffered one has no buffer). On the read mailbox, a toggled repeat request
    /// (activate bit 1) makes the application put its last answer back and toggle the
    /// repeat acknowledge (PDI control bit 1) — how a master recovers an answer whose
    /// frame was lost (section I, 8.6, Figure 26). Enabling the mailbox starts with
    /// request and acknowledge equal.
    fn on_sync_manager_write(&mut self, read_mailbox_was_active: bool, enabled_before: u8) {
        for n in 0..sm::COUNT {
            let s = SyncManager::read_from(&self.memory, n);
            if s.enabled() && enabled_before & (1 << n) == 0 {
                // Just enabled: an empty mailbox, or no buffer completed yet.
                let fresh = match s.kind() {
                    Kind::BufferedRead | Kind::BufferedWrite => status::NO_BUFFER,
                    _ => 0,
                };
                sm::set_status(&mut self.memory, n, fresh);
            }
            if !s.enabled() {
                let reset = match s.kind() {
                    Kind::BufferedRead | Kind::BufferedWrite => status::NO_BUFFER,
                    _ => 0,
                };
                sm::set_status(&mut self.memory, n, reset);
                if s.kind() == Kind::MailboxRead {
                    self.answered = false;
                    self.answer_due = None;
                }
                // A mailbox set up anew starts its counting anew.
                if s.kind() == Kind::MailboxWrite {
                    self.mailbox_counter = 0;
                }
            }
        }
        self.set_up_output_buffers();
        let Some((n, s)) = self.mailbox(Kind::MailboxRead) else {
            return;
        };
        let base = sm::base(n);
        let (request, pdi) = (s.activate, s.pdi_control);
        if request & sm::activate::REPEAT == pdi & sm::activate::REPEAT {
            return;
        }
        if read_mailbox_was_active && self.answered {
            sm::set_status(&mut self.memory, n, s.status | status::MAILBOX_FULL);
        }
        let ack = (pdi & !sm::activate::REPEAT) | (request & sm::activate::REPEAT);
        self.memory.pdi_write(base + 7, &[ack]);
    }

    /// Writes the answer the firmware worked on to SM1 and marks it full, once it is due.
    fn post_answer(&mut self) {
        if self
            .answer_due
            .as_ref()
            .is_none_or(|(due, _)| *due > self.now)
        {
            return;
        }
        let Some((_, area)) = self.answer_due.take() else {
            return;
        };
        let Some((k, o)) = self.mailbox(Kind::MailboxRead) else {
            return;
        };
        self.memory.pdi_write(o.start, &area);
        sm::set_status(&mut self.memory, k, o.status | status::MAILBOX_FULL);
        self.answered = true;
    }

    /// Keeps one application copy per enabled buffered output SyncManager, as configured.
    fn set_up_output_buffers(&mut self) {
        for n in 0..sm::COUNT {
            let s = SyncManager::read_from(&self.memory, n);
            let wanted = s.enabled() && s.kind() == Kind::BufferedWrite && s.last().is_some();
            let at = self.outputs.iter().position(|b| b.sm == n);
            match (wanted, at) {
                (true, Some(i)) => {
                    let same = self.outputs.get(i).is_some_and(|b| {
                        b.start == s.start && b.data.len() == usize::from(s.length)
                    });
                    if !same {
                        self.outputs.remove(i);
                        self.outputs.push(self.fresh_buffer(n, s));
                    }
                }
                (true, None) => self.outputs.push(self.fresh_buffer(n, s)),
                (false, Some(i)) => {
                    self.outputs.remove(i);
                }
                (false, None) => {}
            }
        }
    }

    /// A new output buffer: the application sees what the memory holds until the master
    /// completes one.
    fn fresh_buffer(&self, n: u16, s: SyncManager) -> OutputBuffer {
        let len = usize::from(s.length);
        OutputBuffer {
            sm: n,
            start: s.start,
            data: self
                .memory
                .raw(s.start, len)
                .map_or_else(|| vec![0; len], <[u8]>::to_vec),
        }
    }

    /// A request arrived in the write mailbox (SyncManager `n`): serve it, put the answer
    /// in the read mailbox and mark that full; the write mailbox is empty again once the
    /// firmware took the request.
    ///
    /// As a real slave's firmware: while its send mailbox still holds an answer the master
    /// has not read, it cannot answer, so it leaves the request in the receive mailbox —
    /// which stays full, and the ESC refuses further writes (working counter 0) — until
    /// the master reads the answer. A request whose non-zero counter repeats the last
    /// one's is a repeat (the master did not see its write taken) and is discarded
    /// (ETG.1000.6 Table 29; 0 is the start value and never a repeat).
    fn on_mailbox_write(&mut self, n: u16, s: SyncManager) {
        self.publish_sync_objects();
        let Some(od) = self.od.as_mut() else { return };
        let out = (0..sm::COUNT)
            .map(|k| (k, SyncManager::read_from(&self.memory, k)))
            .find(|(_, o)| o.enabled() && o.kind() == Kind::MailboxRead);
        let busy = self.answer_due.is_some();
        if busy || out.is_some_and(|(_, o)| o.status & status::MAILBOX_FULL != 0) {
            return;
        }
        let mut request = vec![0u8; usize::from(s.length)];
        self.memory.ecat_read(s.start, &mut request, false);
        sm::set_status(&mut self.memory, n, s.status & !status::MAILBOX_FULL);
        let counter = request.get(5).map_or(0, |b| (b >> 4) & 0x07);
        if counter != 0 && counter == self.mailbox_counter {
            return;
        }
        self.mailbox_counter = counter;
        let out_len = out.map_or(0, |(_, o)| usize::from(o.length));
        // The drive's objects are live: its values in before, what was written out after.
        self.device.publish_objects(od);
        let response = coe::serve(od, &mut self.sdo, &request, out_len);
        self.device.take_objects(od);
        let Some(response) = response else {
            return;
        };
        if out.is_none() || response.len() > out_len {
            return;
        }
        let mut area = vec![0u8; out_len];
        if let Some(dst) = area.get_mut(..response.len()) {
            dst.copy_from_slice(&response);
        }
        let due = self.now.saturating_add(self.firmware.mailbox_response_ns);
        self.answer_due = Some((due, area));
        self.post_answer();
        // The master may have written the sync error counter limit.
        if let Some(limit) = self
            .od
            .as_ref()
            .and_then(|od| od.read(ERROR_SETTINGS, 2).ok())
            .and_then(|v| <[u8; 2]>::try_from(v.get(..2)?).ok())
            .map(u16::from_le_bytes)
        {
            self.firmware.sync_error_limit = limit.max(1);
        }
    }

    /// Puts what the firmware counts into its object dictionary before the master reads
    /// it by SDO: 0x1C32 SM output parameter (ETG.1020: :01 sync type, :02 cycle time,
    /// :0B SM event missed, :0C cycle time too small, :20 sync error) and 0x10F1 error
    /// settings (:02 sync error counter limit, writable).
    fn publish_sync_objects(&mut self) {
        let cycle = self
            .memory
            .read_u32(crate::esc::registers::DC_SYNC0_CYCLE_TIME);
        let (sync, limit, dc_mode) = (self.sync, self.firmware.sync_error_limit, self.dc_mode);
        let Some(od) = self.od.as_mut() else { return };
        // Sync type: 2 synchronous with SYNC0, 1 synchronous with the SM2 event.
        let sync_type: u16 = if dc_mode { 2 } else { 1 };
        od.insert(SM_OUTPUT_PARAMETER, 0, &[0x20], false);
        od.insert(SM_OUTPUT_PARAMETER, 0x01, &sync_type.to_le_bytes(), false);
        od.insert(SM_OUTPUT_PARAMETER, 0x02, &cycle.to_le_bytes(), false);
        od.insert(
            SM_OUTPUT_PARAMETER,
            0x0B,
            &sync.sm_event_missed.to_le_bytes(),
            false,
        );
        od.insert(
            SM_OUTPUT_PARAMETER,
            0x0C,
            &sync.cycle_time_too_small.to_le_bytes(),
            false,
        );
        od.insert(
            SM_OUTPUT_PARAMETER,
            0x20,
            &[u8::from(sync.sync_error)],
            false,
        );
        if od.read(ERROR_SETTINGS, 2).is_err() {
            od.insert(ERROR_SETTINGS, 0, &[2], false);
            od.insert(ERROR_SETTINGS, 1, &0u32.to_le_bytes(), false);
            od.insert(ERROR_SETTINGS, 2, &limit.to_le_bytes(), true);
        }
    }

    /// Writes AL status and AL status code. Leaving Op stops the output handler: the
    /// outputs it had are no longer valid, Op again needs fresh ones (the slave stack
    /// code clears its "first outputs received" there).
    /// Puts the slave in `state` at once, as if the master had taken it there (tests of
    /// device models that need a state, not the path to it).
    #[cfg(test)]
    pub(crate) fn force_state(&mut self, state: AlState) {
        self.set_al(u16::from(state.raw()), AlStatusCode::NoError);
    }

    fn set_al(&mut self, status: u16, code: AlStatusCode) {
        let was_op = AlState::from_bits(self.al_status()) == AlState::Op;
        if was_op && AlState::from_bits(status) != AlState::Op {
            self.outputs_received = false;
            self.take_safe_outputs();
        }
        self.memory.pdi_write(AL_STATUS, &status.to_le_bytes());
        self.memory
            .pdi_write(AL_STATUS_CODE, &code.raw().to_le_bytes());
    }

    /// Whether the ESC copies AL control to AL status itself (device emulation).
    fn device_emulation(&self) -> bool {
        self.byte(ESC_CONFIG) & DEVICE_EMULATION != 0
    }

    /// The master wrote AL control. Device emulation: the ESC copies the requested state
    /// at once. Otherwise the firmware checks the request (the standard's rules and its
    /// own: mailbox, SyncManagers, mapping, DC) and refuses at once with the code, or
    /// takes the transition, which completes after its time ([`Firmware::times`]) and,
    /// for SafeOp → Op, once what the device needs is there.
    fn on_al_control(&mut self) {
        let now = self.arrival.port0;
        let control = self.memory.read_u16(AL_CONTROL);
        if self.device_emulation() {
            let state = AlState::from_bits(control);
            self.pending = None;
            self.set_al(u16::from(state.raw()), AlStatusCode::NoError);
            return;
        }
        let status = self.memory.read_u16(AL_STATUS);
        let code = AlStatusCode::from_raw(self.memory.read_u16(AL_STATUS_CODE));
        let current = AlState::from_bits(status);
        let requested = AlState::from_bits(control);
        if self.pending.is_some_and(|p| p.to == requested) && control & al::ERROR_BIT == 0 {
            // Asked again for the state it is on its way to: it keeps going.
            return;
        }
        self.pending = None;
        let checks = self.checks();
        let out = al::on_control(status, code, control, false, |from, to| {
            checks.check(from, to)
        });
        let after = AlState::from_bits(out.status);
        if out.status & al::ERROR_BIT != 0 || after == current {
            self.set_al(out.status, out.code);
            return;
        }
        // Accepted: the error indicator (if acknowledged) clears now, the state follows
        // when the firmware is done.
        self.set_al(u16::from(current.raw()), AlStatusCode::NoError);
        if let Some(od) = self.od.as_mut() {
            // The mapping is frozen from the request on.
            od.set_pre_op(false);
        }
        if (current, after) == (AlState::PreOp, AlState::SafeOp) {
            self.outputs_received = false;
            self.dc_mode = self.byte(DC_ACTIVATION) & DC_SYNC0 != 0;
            self.sync = SyncCounters {
                sync0_seen: self.sync0_events(),
                ..SyncCounters::default()
            };
        }
        self.pending = Some(Pending {
            from: current,
            to: after,
            due: now.saturating_add(self.firmware.times.of(current, after)),
            deadline: now.saturating_add(SAFEOP_OP_TIMEOUT_NS),
        });
        self.run_transition(now);
    }

    /// Completes the pending transition if its time has come and what it waits for is
    /// there; refuses it when it waited too long.
    fn run_transition(&mut self, t: u64) {
        let Some(p) = self.pending else { return };
        if t < p.due {
            return;
        }
        if (p.from, p.to) == (AlState::SafeOp, AlState::Op) {
            let sync_ok = !self.dc_mode || self.sync0_events() > self.sync0_at_safeop;
            let outputs_ok = !self.firmware.op_needs_outputs || self.outputs_received;
            if !(sync_ok && outputs_ok) {
                if t >= p.deadline {
                    self.pending = None;
                    let code = if sync_ok {
                        AlStatusCode::SyncManagerWatchdog
                    } else {
                        AlStatusCode::NoSyncError
                    };
                    self.set_al(u16::from(AlState::SafeOp.raw()) | al::ERROR_BIT, code);
                }
                return;
            }
        }
        self.pending = None;
        if p.to == AlState::Op {
            // The output handler starts afresh: the sync supervision too.
            self.sync.sm_event_missed = 0;
            self.sync.sync_error = false;
        }
        if (p.from, p.to) == (AlState::PreOp, AlState::SafeOp) {
            let layout = self
                .od
                .as_ref()
                .and_then(|od| od.pdo_rules().map(|rules| pdo::layout(od, rules)));
            if let Some(Ok(layout)) = layout {
                self.device.configure_pdo(layout);
            }
            self.sync0_at_safeop = self.sync0_events();
        }
        if let Some(od) = self.od.as_mut() {
            od.set_pre_op(p.to == AlState::PreOp);
        }
        self.set_al(u16::from(p.to.raw()), AlStatusCode::NoError);
    }

    /// What the firmware checks, gathered from the registers and the object dictionary
    /// before the state machine runs.
    fn checks(&self) -> Checks {
        let sms: Vec<SyncManager> = (0..sm::COUNT)
            .map(|n| SyncManager::read_from(&self.memory, n))
            .collect();
        let layout = self
            .od
            .as_ref()
            .and_then(|od| {
                od.pdo_rules()
                    .map(|rules| (pdo::layout(od, rules), rules.max_bytes))
            })
            .map(|(l, max)| l.map(|l| (l.output_bytes(), l.input_bytes(), max)).ok());
        Checks {
            sms,
            mailbox: self.description.mailbox,
            layout,
            dc_activation: self.byte(DC_ACTIVATION),
            requires_dc: self.firmware.requires_dc,
        }
    }
}

/// Swaps an output SyncManager's memory (the buffer the master writes) with the
/// application's completed copy, around the application's step.
fn swap_buffer(mem: &mut Memory, b: &mut OutputBuffer) {
    let len = b.data.len();
    let Some(area) = mem.raw(b.start, len).map(<[u8]>::to_vec) else {
        return;
    };
    mem.pdi_write(b.start, &b.data);
    b.data.copy_from_slice(&area);
}

/// What the firmware checks of a requested transition (ETG.1000.6 Table 11 codes, as the
/// slave stack code raises them).
struct Checks {
    sms: Vec<SyncManager>,
    /// The mailbox the EEPROM describes: (receive offset, size, send offset, size).
    mailbox: Option<(u16, u16, u16, u16)>,
    /// The mapped process data (output bytes, input bytes, the most the device's buffer
    /// takes each way); `Some(None)`: a mapping the device cannot run; `None`: no CoE
    /// mapping (fixed PDOs).
    layout: Option<Option<(usize, usize, usize)>>,
    dc_activation: u8,
    requires_dc: bool,
}

impl Checks {
    fn check(&self, from: AlState, to: AlState) -> Result<(), AlStatusCode> {
        let up_from_init = from == AlState::Init && matches!(to, AlState::PreOp);
        let to_safeop = from == AlState::PreOp && to == AlState::SafeOp;
        if up_from_init || to_safeop {
            self.check_areas()?;
            self.check_mailbox()?;
        }
        if to_safeop {
            self.check_process_data()?;
            self.check_dc()?;
        }
        Ok(())
    }

    /// 0x0017: an enabled SyncManager outside process RAM, or two that overlap (three
    /// buffers' worth in buffered mode).
    fn check_areas(&self) -> Result<(), AlStatusCode> {
        let ram = u32::from(PROCESS_RAM)..u32::from(PROCESS_RAM) + RAM_BYTES as u32;
        let used: Vec<(u32, u32)> = self
            .sms
            .iter()
            .filter(|s| s.enabled() && s.length > 0)
            .map(|s| (u32::from(s.start), u32::from(s.start) + s.footprint()))
            .collect();
        for (i, &(a, b)) in used.iter().enumerate() {
            if a < ram.start || b > ram.end {
                return Err(AlStatusCode::InvalidSyncManagerConfig);
            }
            if used.iter().skip(i + 1).any(|&(c, d)| a < d && c < b) {
                return Err(AlStatusCode::InvalidSyncManagerConfig);
            }
        }
        Ok(())
    }

    /// 0x0016: a device with a mailbox needs SyncManager 0 as its receive mailbox and 1
    /// as its send mailbox (mailbox mode, the right direction, enabled) where its EEPROM
    /// says, at least [`MIN_MAILBOX_BYTES`] and at most the EEPROM's size.
    fn check_mailbox(&self) -> Result<(), AlStatusCode> {
        let Some((rx_at, rx_len, tx_at, tx_len)) = self.mailbox else {
            return Ok(());
        };
        let ok = |s: Option<&SyncManager>, kind: Kind, at: u16, max: u16| {
            s.is_some_and(|s| {
                s.enabled()
                    && s.kind() == kind
                    && s.start == at
                    && (MIN_MAILBOX_BYTES..=max).contains(&s.length)
            })
        };
        if ok(self.sms.first(), Kind::MailboxWrite, rx_at, rx_len)
            && ok(self.sms.get(1), Kind::MailboxRead, tx_at, tx_len)
        {
            Ok(())
        } else {
            Err(AlStatusCode::InvalidMailboxConfigPreOp)
        }
    }

    /// 0x001D/0x001E: the process data the master set up must be what the assigned PDOs
    /// say (all of them, one after the other): the output SyncManager (2) enabled,
    /// buffered, written by the master and as long as the outputs; the input SyncManager
    /// (3) likewise for the inputs; neither more than the device's buffer.
    fn check_process_data(&self) -> Result<(), AlStatusCode> {
        let Some(layout) = self.layout else {
            return Ok(());
        };
        let (outputs, inputs, max) = layout.ok_or(AlStatusCode::InvalidOutputConfig)?;
        if outputs > max {
            return Err(AlStatusCode::InvalidOutputConfig);
        }
        if inputs > max {
            return Err(AlStatusCode::InvalidInputConfig);
        }
        let fits = |s: Option<&SyncManager>, kind: Kind, bytes: usize| {
            s.is_some_and(|s| {
                if bytes == 0 {
                    !s.enabled()
                } else {
                    s.enabled() && s.kind() == kind && usize::from(s.length) == bytes
                }
            })
        };
        if !fits(self.sms.get(2), Kind::BufferedWrite, outputs) {
            return Err(AlStatusCode::InvalidOutputConfig);
        }
        if !fits(self.sms.get(3), Kind::BufferedRead, inputs) {
            return Err(AlStatusCode::InvalidInputConfig);
        }
        Ok(())
    }

    /// 0x0030: the cyclic unit on without SYNC0 (SYNC1 alone included), or a device that
    /// runs only on SYNC0 without it (the slave stack code's checks at PreOp → SafeOp).
    fn check_dc(&self) -> Result<(), AlStatusCode> {
        let a = self.dc_activation;
        let cyclic = a & DC_CYCLIC != 0;
        let sync0 = a & DC_SYNC0 != 0;
        let sync1 = a & DC_SYNC1 != 0;
        // No SYNC0 while the cyclic unit or SYNC1 is on; or no SYNC0 for a device that
        // needs it.
        let without_sync0 = !sync0 && (cyclic || sync1);
        if without_sync0 || (self.requires_dc && !(cyclic && sync0)) {
            return Err(AlStatusCode::InvalidDcSyncConfig);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::{self, ServoOptions, MAILBOX_IN_AT, MAILBOX_OUT_AT};
    use crate::esc::datagram::Command;
    use crate::esc::sync_manager::activate::REPEAT;
    use crate::esc::sync_manager::base as sm_base;
    use crate::esc::sync_manager::status::MAILBOX_FULL;

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

    #[test]
    fn a_slow_firmware_answers_when_its_time_has_come() {
        let mut s = servo_with_mailbox();
        s.firmware.mailbox_response_ns = 2_000_000;
        let sm0_full = |s: &Slave| s.byte(sm_base(0) + 5) & MAILBOX_FULL != 0;
        s.advance_to(1_000_000);
        assert_eq!(
            fp(&mut s, Command::Fpwr, MAILBOX_OUT_AT, &upload_1018_01(1)).0,
            1
        );
        assert!(!full(&s), "no answer yet");
        assert_eq!(fp(&mut s, Command::Fprd, MAILBOX_IN_AT, &[0; 128]).0, 0);
        // A second request while the firmware works waits in SM0.
        assert_eq!(
            fp(&mut s, Command::Fpwr, MAILBOX_OUT_AT, &upload_1018_01(2)).0,
            1
        );
        assert!(sm0_full(&s));
        s.advance_to(2_999_999);
        assert!(!full(&s));
        s.advance_to(3_000_000);
        assert!(full(&s), "answered 2 ms later");
        let (wkc, answer) = fp(&mut s, Command::Fprd, MAILBOX_IN_AT, &[0; 128]);
        assert_eq!((wkc, &answer[8..12]), (1, &[0x43, 0x18, 0x10, 0x01][..]));
        // Read: the firmware takes the waiting request, and answers it 2 ms on.
        assert!(!sm0_full(&s) && !full(&s));
        s.advance_to(5_000_000);
        assert!(full(&s));
    }

    #[test]
    fn a_repeated_counter_is_discarded_and_zero_never_repeats() {
        let mut s = servo_with_mailbox();
        let served = |s: &mut Slave, counter: u8| {
            assert_eq!(
                fp(s, Command::Fpwr, MAILBOX_OUT_AT, &upload_1018_01(counter)).0,
                1,
                "the ESC takes the write"
            );
            let answered = full(s);
            if answered {
                assert_eq!(fp(s, Command::Fprd, MAILBOX_IN_AT, &[0; 128]).0, 1);
            }
            answered
        };
        assert!(served(&mut s, 5));
        assert!(
            !served(&mut s, 5),
            "the same counter again: a repeat, discarded"
        );
        assert!(served(&mut s, 6));
        assert!(served(&mut s, 0));
        assert!(served(&mut s, 0), "0 is the start value, never a repeat");
        assert!(served(&mut s, 1));
    }

    #[test]
    fn a_request_waits_in_the_receive_mailbox_until_the_answer_before_is_read() {
        let mut s = servo_with_mailbox();
        let sm0_full = |s: &Slave| s.byte(sm_base(0) + 5) & MAILBOX_FULL != 0;
        assert_eq!(
            fp(&mut s, Command::Fpwr, MAILBOX_OUT_AT, &upload_1018_01(1)).0,
            1
        );
        assert!(full(&s) && !sm0_full(&s));
        // The first answer is not read: the second request cannot be answered and stays.
        assert_eq!(
            fp(&mut s, Command::Fpwr, MAILBOX_OUT_AT, &upload_1018_01(2)).0,
            1
        );
        assert!(sm0_full(&s), "not taken by the firmware");
        assert_eq!(
            fp(&mut s, Command::Fpwr, MAILBOX_OUT_AT, &upload_1018_01(3)).0,
            0,
            "a write to a full receive mailbox is refused, the request lost"
        );
        // Reading the first answer lets the firmware take the second.
        assert_eq!(fp(&mut s, Command::Fprd, MAILBOX_IN_AT, &[0; 128]).0, 1);
        assert!(!sm0_full(&s));
        assert!(full(&s), "the second request's answer");
        let (_, answer) = fp(&mut s, Command::Fprd, MAILBOX_IN_AT, &[0; 128]);
        assert_eq!(&answer[8..12], &[0x43, 0x18, 0x10, 0x01]);
    }

    /// A slave with no firmware of its own and SyncManager `n` set to `regs`.
    fn bare_with_sm(n: u16, regs: [u8; 8]) -> Slave {
        let mut s = Slave::new(catalog::encoder_description(1));
        assert_eq!(fp(&mut s, Command::Fpwr, sm_base(n), &regs).0, 1);
        s
    }

    #[test]
    fn a_partial_write_does_not_reach_the_application_in_three_buffer_mode() {
        // SM2: 6 bytes at 0x1100, buffered, master writes, watchdog trigger (0x64).
        let mut s = bare_with_sm(2, [0x00, 0x11, 6, 0, 0x64, 0, 1, 0]);
        let status = |s: &Slave| s.byte(sm_base(2) + 5);
        assert_eq!(status(&s), 0x30, "no buffer completed yet");
        assert_eq!(s.application_outputs(2), Some(&[0u8; 6][..]));
        // The first half: the application still has the old buffer.
        assert_eq!(fp(&mut s, Command::Fpwr, 0x1100, &[1, 2, 3]).0, 1);
        assert_eq!(s.application_outputs(2), Some(&[0u8; 6][..]));
        assert_eq!(status(&s), 0x30);
        // The rest, to the last byte: buffer 0 completed, write event (bit 0).
        assert_eq!(fp(&mut s, Command::Fpwr, 0x1103, &[4, 5, 6]).0, 1);
        assert_eq!(s.application_outputs(2), Some(&[1u8, 2, 3, 4, 5, 6][..]));
        assert_eq!(status(&s), 0x01);
        // The application reads it: the event clears; the next buffer is number 1.
        s.tick(0.001);
        assert_eq!(status(&s), 0x00);
        fp(&mut s, Command::Fpwr, 0x1100, &[9; 6]);
        assert_eq!(status(&s), 0x11);
        // The master overwrites the first byte of the next buffer and stops: the
        // application keeps the completed one, the memory the master sees holds its write.
        fp(&mut s, Command::Fpwr, 0x1100, &[7]);
        assert_eq!(s.application_outputs(2), Some(&[9u8; 6][..]));
        s.tick(0.001);
        assert_eq!(s.application_outputs(2), Some(&[9u8; 6][..]));
        assert_eq!(s.memory().raw(0x1100, 2), Some(&[7u8, 9][..]));
    }

    #[test]
    fn an_input_syncmanager_shows_the_masters_reads_and_the_applications_buffers() {
        // SM3: 6 bytes at 0x1400, buffered, master reads (0x20).
        let mut s = bare_with_sm(3, [0x00, 0x14, 6, 0, 0x20, 0, 1, 0]);
        let status = |s: &Slave| s.byte(sm_base(3) + 5);
        assert_eq!(status(&s), 0x30);
        s.tick(0.001);
        assert_eq!(status(&s), 0x00, "the application wrote buffer 0");
        assert_eq!(fp(&mut s, Command::Fprd, 0x1400, &[0; 5]).0, 1);
        assert_eq!(status(&s), 0x00, "not read to the last byte");
        assert_eq!(fp(&mut s, Command::Fprd, 0x1405, &[0; 1]).0, 1);
        assert_eq!(status(&s), 0x02, "read event");
        s.tick(0.001);
        assert_eq!(
            status(&s),
            0x10,
            "event cleared by the next write, buffer 1"
        );
    }

    #[test]
    fn mailbox_rules_follow_the_control_register_not_the_number() {
        // A device without a mailbox protocol, SM4 set up as a receive mailbox (0x26):
        // the first write fills it, nothing empties it, the second is refused.
        let mut s = bare_with_sm(4, [0x00, 0x12, 64, 0, 0x26, 0, 1, 0]);
        assert_eq!(fp(&mut s, Command::Fpwr, 0x1200, &[0x11; 64]).0, 1);
        assert_eq!(s.byte(sm_base(4) + 5) & MAILBOX_FULL, MAILBOX_FULL);
        assert_eq!(fp(&mut s, Command::Fpwr, 0x1200, &[0x22; 64]).0, 0, "full");
        assert_eq!(
            s.memory().raw(0x1200, 1),
            Some(&[0x11][..]),
            "not overwritten"
        );
        // SM6 as a send mailbox (0x22): empty, so its area cannot be read.
        fp(
            &mut s,
            Command::Fpwr,
            sm_base(6),
            &[0x00, 0x13, 64, 0, 0x22, 0, 1, 0],
        );
        let (wkc, data) = fp(&mut s, Command::Fprd, 0x1300, &[0xAA; 8]);
        assert_eq!((wkc, data), (0, vec![0xAA; 8]));
        // The same SM6 as buffered inputs (0x20) reads fine: the mode decides.
        fp(&mut s, Command::Fpwr, sm_base(6) + 4, &[0x20]);
        assert_eq!(fp(&mut s, Command::Fprd, 0x1300, &[0xAA; 8]).0, 1);
    }
}
