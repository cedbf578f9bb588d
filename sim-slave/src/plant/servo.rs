//! A CiA-402 servo drive in cyclic synchronous position (CSP) mode: the device side of
//! the power state machine from `gantry-drives` (the same table the master uses), and a
//! motor + load that follows the commanded position with a finite bandwidth, so the master
//! sees a following error.
//!
//! Process data follows the PDO layout the master mapped (see `coe::pdo`); until then
//! the power-up mapping: outputs `0x6040 controlword: u16, 0x607A target position: i32`;
//! inputs `0x6041 statusword: u16, 0x6064 position actual value: i32`.

use gantry_drives::cia402::objects::{self, ObjectId};
use gantry_drives::cia402::pdo::PdoLayout;
use gantry_drives::cia402::{Controlword, DeviceStateMachine, State};

use crate::esc::memory::Memory;
use crate::plant::record::DriveRecord;

/// Most process data bytes per direction the model handles.
const MAX_PDO_BYTES: usize = 64;

/// Error code (0x603F) of a fault by process-data watchdog: CiA 301 0x8700 "sync
/// controller" family, which EtherCAT drives use for a lost SyncManager watchdog.
pub const ERROR_SYNC_WATCHDOG: u16 = 0x8700;

/// Modes of operation: cyclic synchronous position, velocity, torque.
const CSP: i8 = 8;
const CSV: i8 = 9;
const CST: i8 = 10;

/// Touch probe function bits (CiA 402 0x60B8): enable probe 1; continuous (else first
/// event only); trigger on the encoder's zero impulse (else the probe input); sample the
/// positive edge.
mod tp {
    pub const ENABLE_1: u16 = 1 << 0;
    pub const CONTINUOUS_1: u16 = 1 << 1;
    pub const ZERO_IMPULSE_1: u16 = 1 << 2;
    pub const POSITIVE_EDGE_1: u16 = 1 << 4;
    /// Touch probe status (0x60B9): probe 1 enabled; positive edge value stored.
    pub const STATUS_ENABLED_1: u16 = 1 << 0;
    pub const STATUS_STORED_1: u16 = 1 << 1;
}

/// A servo drive model.
#[derive(Clone, Debug)]
pub struct ServoDrive {
    /// Where the output process data lies in the ESC's RAM (SM2).
    pub outputs_at: u16,
    /// Where the input process data lies (SM3).
    pub inputs_at: u16,
    /// Position loop bandwidth (Hz): the load follows the set position as a first-order lag.
    pub bandwidth_hz: f64,
    /// Encoder counts per motor revolution (the index pulse comes once per revolution).
    pub counts_per_rev: u32,
    /// Where in the revolution the index pulse sits (counts).
    pub index_at: u32,
    /// Motor pole pairs (electrical revolutions per mechanical one).
    pub pole_pairs: u32,
    /// The motor's true commutation offset (counts), unknown to the master until it is
    /// commissioned: the drive's setting is `commutation_setting`.
    pub commutation_offset: i32,
    /// The commutation offset the drive was told (counts).
    pub commutation_setting: i32,
    /// Acceleration at rated torque (counts/s²), for CST.
    pub rated_acceleration: f64,
    state: DeviceStateMachine,
    error_code: u16,
    /// Load position (counts, fractional).
    position: f64,
    /// Load velocity (counts/s) of the last step.
    velocity: f64,
    /// Last target position received.
    target: i32,
    target_velocity: i32,
    target_torque: i16,
    /// Last controlword received.
    controlword: Controlword,
    /// A touch probe function received, not yet applied.
    pending_touch_probe: Option<u16>,
    mode: i8,
    touch_probe_function: u16,
    touch_probe_status: u16,
    touch_probe_pos1: i32,
    layout: PdoLayout,
    record: DriveRecord,
}

impl ServoDrive {
    /// A drive at position `start_counts` (the absolute encoder's value at power-up).
    pub fn new(outputs_at: u16, inputs_at: u16, start_counts: i32) -> Self {
        Self {
            outputs_at,
            inputs_at,
            bandwidth_hz: 200.0,
            state: DeviceStateMachine::ready(),
            error_code: 0,
            position: f64::from(start_counts),
            velocity: 0.0,
            target: start_counts,
            target_velocity: 0,
            target_torque: 0,
            controlword: Controlword(0),
            pending_touch_probe: None,
            mode: CSP,
            touch_probe_function: 0,
            touch_probe_status: 0,
            touch_probe_pos1: 0,
            counts_per_rev: 1 << 17,
            index_at: 1000,
            pole_pairs: 5,
            commutation_offset: 0,
            commutation_setting: 0,
            rated_acceleration: 2.0e7,
            layout: PdoLayout::csp_minimal(),
            record: DriveRecord::default(),
        }
    }

    /// cos of the electrical angle by which the commutation setting misses the motor's
    /// true offset: 1 when commissioned, 0 at 90° electrical (no torque at all).
    pub fn torque_efficiency(&self) -> f64 {
        let error = f64::from(self.commutation_offset) - f64::from(self.commutation_setting);
        let electrical = 2.0 * core::f64::consts::PI * f64::from(self.pole_pairs) * error
            / f64::from(self.counts_per_rev.max(1));
        electrical.cos()
    }

    fn set_touch_probe(&mut self, function: u16) {
        if function & tp::ENABLE_1 == 0 {
            self.touch_probe_status = 0;
        } else if self.touch_probe_function & tp::ENABLE_1 == 0 {
            // Rising edge of the enable: arm, nothing stored yet.
            self.touch_probe_status = tp::STATUS_ENABLED_1;
        }
        self.touch_probe_function = function;
    }

    /// The index pulse: once per revolution at `index_at`. Touch probe 1, armed on the zero
    /// impulse with the positive edge, stores the exact position where it was crossed.
    fn watch_index(&mut self, from: f64, to: f64) {
        let f = self.touch_probe_function;
        let armed = f & tp::ENABLE_1 != 0
            && f & tp::ZERO_IMPULSE_1 != 0
            && f & tp::POSITIVE_EDGE_1 != 0
            && (f & tp::CONTINUOUS_1 != 0 || self.touch_probe_status & tp::STATUS_STORED_1 == 0);
        if !armed || from == to {
            return;
        }
        let rev = f64::from(self.counts_per_rev.max(1));
        let at = f64::from(self.index_at);
        // The first index position passed going from `from` to `to`.
        let crossed = if to > from {
            let k = ((from - at) / rev).floor() + 1.0;
            let p = at + k * rev;
            (p <= to).then_some(p)
        } else {
            let k = ((from - at) / rev).ceil() - 1.0;
            let p = at + k * rev;
            (p >= to).then_some(p)
        };
        if let Some(p) = crossed {
            self.touch_probe_pos1 = p.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32;
            self.touch_probe_status |= tp::STATUS_STORED_1;
        }
    }

    /// Uses the layout the master mapped (at PreOp → SafeOp).
    pub fn configure(&mut self, layout: PdoLayout) {
        self.layout = layout;
    }

    /// The process data layout in use.
    pub fn layout(&self) -> &PdoLayout {
        &self.layout
    }

    /// Power state.
    pub fn state(&self) -> State {
        self.state.state()
    }

    /// Load position (counts).
    pub fn position(&self) -> f64 {
        self.position
    }

    /// Position actual value (0x6064): the load position rounded to whole counts, as the
    /// drive reports it and as switch cams on this axis see it.
    pub fn actual_counts(&self) -> i32 {
        self.position
            .round()
            .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
    }

    /// The master stopped sending process data: a drive with power on faults (fault
    /// reaction: it stops on its own; this model's load stops where it is).
    pub fn on_watchdog(&mut self) {
        if matches!(
            self.state.state(),
            State::OperationEnabled | State::SwitchedOn | State::QuickStopActive
        ) {
            self.state.fault();
            self.error_code = ERROR_SYNC_WATCHDOG;
            self.record.fault(ERROR_SYNC_WATCHDOG);
        }
    }

    /// What the drive recorded of the setpoints it took.
    pub fn record(&self) -> &DriveRecord {
        &self.record
    }

    /// Last fault's error code (0x603F), 0 when none.
    pub fn error_code(&self) -> u16 {
        self.error_code
    }

    /// One cycle: take the outputs, run the drive for `dt_s`, publish the inputs.
    pub fn step(&mut self, mem: &mut Memory, dt_s: f64) {
        self.take_outputs(mem);
        self.run(dt_s);
        self.publish_inputs(mem);
    }

    /// (a) Takes the outputs: reads the process data the master wrote (SM2's buffer in the
    /// ESC RAM) into the drive's command: controlword, target values, mode, touch probe
    /// function. A real drive does this at its SYNC0 edge (DC) or when the frame has
    /// written SM2 (free run); the target taken is what [`DriveRecord`] judges the master by.
    pub fn take_outputs(&mut self, mem: &Memory) {
        let mut out = [0u8; MAX_PDO_BYTES];
        let n_out = self.layout.output_bytes().min(MAX_PDO_BYTES);
        if let Some(o) = out.get_mut(..n_out) {
            mem.ecat_read(self.outputs_at, o, false);
        }
        let mut at = 0;
        for o in &self.layout.outputs {
            let v = field(&out, at, o.kind.size());
            match o.index {
                0x6040 => self.controlword = Controlword(v as u16),
                0x607A => self.target = v as i32,
                0x60FF => self.target_velocity = v as i32,
                0x6071 => self.target_torque = v as i16,
                0x60B8 => self.pending_touch_probe = Some(v as u16),
                // A mode the drive does not have is not taken (the display keeps the old).
                0x6060 if matches!(v as i8, CSP | CSV | CST) => self.mode = v as i8,
                _ => {}
            }
            at += o.kind.size();
        }
        if self.state.state() == State::OperationEnabled && self.mode == CSP {
            self.record.target(self.target);
        }
    }

    /// (b) Runs the drive for `dt_s` seconds on the command last taken: the power state
    /// machine, then the plant.
    pub fn run(&mut self, dt_s: f64) {
        if let Some(f) = self.pending_touch_probe.take() {
            self.set_touch_probe(f);
        }
        if self.state.state() == State::FaultReactionActive {
            self.state.fault_reaction_done();
        }
        self.state.control(self.controlword);
        if self.state.state() != State::Fault {
            self.error_code = 0;
        }
        let before = self.position;
        let dt = dt_s.max(0.0);
        if self.state.state() == State::OperationEnabled {
            // A wrong commutation offset costs torque: cos of the electrical angle error.
            let gain = self.torque_efficiency();
            let lag =
                |hz: f64| 1.0 - (-2.0 * core::f64::consts::PI * hz * gain.max(0.02) * dt).exp();
            match self.mode {
                CSV => {
                    let v_target = f64::from(self.target_velocity);
                    self.velocity += (v_target - self.velocity) * lag(2.0 * self.bandwidth_hz);
                    self.position += self.velocity * dt;
                }
                CST => {
                    let torque = f64::from(self.target_torque) / 1000.0;
                    // Viscous friction brings an unloaded motor to a finite speed.
                    let a = torque * gain * self.rated_acceleration - 5.0 * self.velocity;
                    self.velocity += a * dt;
                    self.position += self.velocity * dt;
                }
                _ => {
                    self.position +=
                        (f64::from(self.target) - self.position) * lag(self.bandwidth_hz);
                    self.velocity = if dt > 0.0 {
                        (self.position - before) / dt
                    } else {
                        0.0
                    };
                }
            }
        } else {
            self.velocity = 0.0;
            self.record.disabled();
        }
        self.watch_index(before, self.position);
    }

    /// (c) Publishes the inputs: writes the mapped input objects into SM3's buffer.
    pub fn publish_inputs(&self, mem: &mut Memory) {
        let mut inp = [0u8; MAX_PDO_BYTES];
        let mut at = 0;
        for o in &self.layout.inputs {
            let v = self.input_value(o);
            put(&mut inp, at, o.kind.size(), v);
            at += o.kind.size();
        }
        if let Some(i) = inp.get(..at.min(MAX_PDO_BYTES)) {
            mem.pdi_write(self.inputs_at, i);
        }
    }

    fn input_value(&self, o: &ObjectId) -> i64 {
        let counts = |x: f64| x.round().clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i64;
        match *o {
            objects::STATUSWORD => {
                i64::from(self.state.statusword().0 | gantry_drives::cia402::statusword::REMOTE)
            }
            objects::POSITION_ACTUAL_VALUE => i64::from(self.actual_counts()),
            objects::VELOCITY_ACTUAL_VALUE => counts(self.velocity),
            // Torque follows acceleration; the model has no load inertia, so report 0.
            objects::TORQUE_ACTUAL_VALUE => 0,
            objects::ERROR_CODE => i64::from(self.error_code),
            objects::MODES_OF_OPERATION_DISPLAY => i64::from(self.mode),
            objects::FOLLOWING_ERROR_ACTUAL_VALUE => counts(f64::from(self.target) - self.position),
            objects::TOUCH_PROBE_STATUS => i64::from(self.touch_probe_status),
            objects::TOUCH_PROBE_POS1_POS_VALUE => i64::from(self.touch_probe_pos1),
            objects::DIGITAL_INPUTS => 0,
            _ => 0,
        }
    }
}

/// A little-endian field of `size` bytes at `at`, sign-extended.
fn field(buf: &[u8], at: usize, size: usize) -> i64 {
    let mut b = [0u8; 8];
    if let (Some(dst), Some(src)) = (b.get_mut(..size), buf.get(at..at + size)) {
        dst.copy_from_slice(src);
    }
    let shift = 64 - 8 * size.clamp(1, 8) as u32;
    (i64::from_le_bytes(b) << shift) >> shift
}

/// Writes the low `size` bytes of `v` at `at`.
fn put(buf: &mut [u8], at: usize, size: usize, v: i64) {
    if let (Some(dst), Some(src)) = (buf.get_mut(at..at + size), v.to_le_bytes().get(..size)) {
        dst.copy_from_slice(src);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::esc::registers::PROCESS_RAM;

    fn outputs(mem: &mut Memory, cw: u16, target: i32) {
        let mut b = [0u8; 6];
        b[0..2].copy_from_slice(&cw.to_le_bytes());
        b[2..6].copy_from_slice(&target.to_le_bytes());
        mem.pdi_write(PROCESS_RAM, &b);
    }

    #[test]
    fn enables_through_the_state_machine_and_follows_with_lag() {
        let mut mem = Memory::new();
        let mut d = ServoDrive::new(PROCESS_RAM, PROCESS_RAM + 0x100, 1000);
        for cw in [0x06, 0x07] {
            outputs(&mut mem, cw, 5000);
            d.step(&mut mem, 0.001);
            assert_eq!(
                d.position(),
                1000.0,
                "does not move before Operation enabled"
            );
        }
        outputs(&mut mem, 0x0F, 1000);
        d.step(&mut mem, 0.001);
        assert_eq!(d.state(), State::OperationEnabled);
        outputs(&mut mem, 0x0F, 2000);
        d.step(&mut mem, 0.001);
        let p = d.position();
        assert!(p > 1000.0 && p < 2000.0, "first-order lag: {p}");
        for _ in 0..100 {
            d.step(&mut mem, 0.001);
        }
        assert!((d.position() - 2000.0).abs() < 1.0);
        let mut inp = [0u8; 6];
        mem.ecat_read(PROCESS_RAM + 0x100, &mut inp, false);
        let sw = gantry_drives::cia402::Statusword(u16::from_le_bytes([inp[0], inp[1]]));
        assert_eq!(sw.state(), Some(State::OperationEnabled));
        assert_eq!(i32::from_le_bytes([inp[2], inp[3], inp[4], inp[5]]), 2000);
    }

    /// A servo mapped to `layout`, enabled, with outputs written by `out`.
    fn enabled(layout: PdoLayout, start: i32) -> (ServoDrive, Memory) {
        let mut mem = Memory::new();
        let mut d = ServoDrive::new(PROCESS_RAM, PROCESS_RAM + 0x100, start);
        d.configure(layout);
        for cw in [0x06u16, 0x07, 0x0F] {
            mem.pdi_write(PROCESS_RAM, &cw.to_le_bytes());
            d.step(&mut mem, 0.001);
        }
        assert_eq!(d.state(), State::OperationEnabled);
        (d, mem)
    }

    fn layout(outputs: &[ObjectId], inputs: &[ObjectId]) -> PdoLayout {
        PdoLayout {
            outputs: outputs.to_vec(),
            inputs: inputs.to_vec(),
        }
    }

    #[test]
    fn csv_follows_the_target_velocity_and_cst_accelerates_with_torque() {
        use objects::*;
        // Outputs: controlword, mode, target velocity, target torque.
        let l = layout(
            &[
                CONTROLWORD,
                MODES_OF_OPERATION,
                TARGET_VELOCITY,
                TARGET_TORQUE,
            ],
            &[
                STATUSWORD,
                POSITION_ACTUAL_VALUE,
                MODES_OF_OPERATION_DISPLAY,
            ],
        );
        let (mut d, mut mem) = enabled(l, 0);
        let out = |mem: &mut Memory, mode: i8, v: i32, t: i16| {
            let mut b = [0u8; 9];
            b[0..2].copy_from_slice(&0x0Fu16.to_le_bytes());
            b[2] = mode as u8;
            b[3..7].copy_from_slice(&v.to_le_bytes());
            b[7..9].copy_from_slice(&t.to_le_bytes());
            mem.pdi_write(PROCESS_RAM, &b);
        };
        out(&mut mem, 9, 10_000, 0);
        for _ in 0..1000 {
            d.step(&mut mem, 0.001);
        }
        // 1 s at 10 000 counts/s, less the time the velocity loop took to get there.
        let p = d.position();
        assert!((9_900.0..10_000.0).contains(&p), "CSV: {p}");
        let mut inp = [0u8; 7];
        mem.ecat_read(PROCESS_RAM + 0x100, &mut inp, false);
        assert_eq!(inp[6], 9, "mode display");
        // An unsupported mode (homing, 6) is not taken.
        out(&mut mem, 6, 0, 0);
        d.step(&mut mem, 0.001);
        mem.ecat_read(PROCESS_RAM + 0x100, &mut inp, false);
        assert_eq!(inp[6], 9);
        // CST: torque accelerates; a wrong commutation offset (90° electrical) gives none.
        out(&mut mem, 10, 0, 100);
        let p0 = d.position();
        for _ in 0..100 {
            d.step(&mut mem, 0.001);
        }
        assert!(d.position() - p0 > 1000.0, "CST moves");
        let (mut d2, mut mem2) = enabled(PdoLayout::csp_minimal(), 0);
        d2.configure(layout(
            &[
                CONTROLWORD,
                MODES_OF_OPERATION,
                TARGET_VELOCITY,
                TARGET_TORQUE,
            ],
            &[
                STATUSWORD,
                POSITION_ACTUAL_VALUE,
                MODES_OF_OPERATION_DISPLAY,
            ],
        ));
        d2.counts_per_rev = 20_000;
        d2.commutation_offset = (d2.counts_per_rev / d2.pole_pairs / 4) as i32;
        assert!(d2.torque_efficiency().abs() < 1e-9);
        out(&mut mem2, 10, 0, 100);
        for _ in 0..100 {
            d2.step(&mut mem2, 0.001);
        }
        assert!(d2.position().abs() < 1e-6, "no torque at 90° electrical");
        d2.commutation_setting = d2.commutation_offset;
        assert!((d2.torque_efficiency() - 1.0).abs() < 1e-12, "commissioned");
    }

    #[test]
    fn touch_probe_latches_the_index_pulse_exactly() {
        use objects::*;
        let l = layout(
            &[CONTROLWORD, TARGET_POSITION, TOUCH_PROBE_FUNCTION],
            &[
                STATUSWORD,
                POSITION_ACTUAL_VALUE,
                TOUCH_PROBE_STATUS,
                TOUCH_PROBE_POS1_POS_VALUE,
            ],
        );
        let (mut d, mut mem) = enabled(l, 0);
        let out = |mem: &mut Memory, target: i32, tp: u16| {
            let mut b = [0u8; 8];
            b[0..2].copy_from_slice(&0x0Fu16.to_le_bytes());
            b[2..6].copy_from_slice(&target.to_le_bytes());
            b[6..8].copy_from_slice(&tp.to_le_bytes());
            mem.pdi_write(PROCESS_RAM, &b);
        };
        let read = |mem: &Memory| {
            let mut b = [0u8; 12];
            mem.ecat_read(PROCESS_RAM + 0x100, &mut b, false);
            (
                u16::from_le_bytes([b[6], b[7]]),
                i32::from_le_bytes([b[8], b[9], b[10], b[11]]),
            )
        };
        // Armed (enable, zero impulse, positive edge), single event.
        out(&mut mem, 0, 0x0015);
        d.step(&mut mem, 0.001);
        assert_eq!(read(&mem), (0x0001, 0), "enabled, nothing stored");
        // Move past two index positions (1000 and 1000 + 2^17): the first is stored.
        out(&mut mem, 200_000, 0x0015);
        for _ in 0..500 {
            d.step(&mut mem, 0.001);
        }
        assert_eq!(read(&mem), (0x0003, 1000));
        // Re-arm (enable off, on) and come back: the crossing going down is stored too.
        out(&mut mem, 200_000, 0);
        d.step(&mut mem, 0.001);
        out(&mut mem, 0, 0x0015);
        for _ in 0..500 {
            d.step(&mut mem, 0.001);
        }
        assert_eq!(read(&mem), (0x0003, 1000 + (1 << 17)));
    }
}
