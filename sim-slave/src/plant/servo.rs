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

/// Most process data bytes per direction the model handles.
const MAX_PDO_BYTES: usize = 64;

/// Error code (0x603F) of a fault by process-data watchdog: CiA 301 0x8700 "sync
/// controller" family, which EtherCAT drives use for a lost SyncManager watchdog.
pub const ERROR_SYNC_WATCHDOG: u16 = 0x8700;

/// Modes of operation value of cyclic synchronous position.
const CSP: i8 = 8;

/// A servo drive model.
#[derive(Clone, Debug)]
pub struct ServoDrive {
    /// Where the output process data lies in the ESC's RAM (SM2).
    pub outputs_at: u16,
    /// Where the input process data lies (SM3).
    pub inputs_at: u16,
    /// Position loop bandwidth (Hz): the load follows the set position as a first-order lag.
    pub bandwidth_hz: f64,
    state: DeviceStateMachine,
    error_code: u16,
    /// Load position (counts, fractional).
    position: f64,
    /// Load velocity (counts/s) of the last step.
    velocity: f64,
    /// Last target position received.
    target: i32,
    mode: i8,
    layout: PdoLayout,
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
            mode: CSP,
            layout: PdoLayout::csp_minimal(),
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
        }
    }

    /// Last fault's error code (0x603F), 0 when none.
    pub fn error_code(&self) -> u16 {
        self.error_code
    }

    /// One cycle: read outputs, step the state machine and the plant, write inputs.
    pub fn step(&mut self, mem: &mut Memory, dt_s: f64) {
        let mut out = [0u8; MAX_PDO_BYTES];
        let n_out = self.layout.output_bytes().min(MAX_PDO_BYTES);
        if let Some(o) = out.get_mut(..n_out) {
            mem.ecat_read(self.outputs_at, o, false);
        }
        let mut cw = Controlword(0);
        let mut at = 0;
        for o in &self.layout.outputs {
            let v = field(&out, at, o.kind.size());
            match o.index {
                0x6040 => cw = Controlword(v as u16),
                0x607A => self.target = v as i32,
                0x6060 => self.mode = v as i8,
                _ => {}
            }
            at += o.kind.size();
        }
        if self.state.state() == State::FaultReactionActive {
            self.state.fault_reaction_done();
        }
        self.state.control(cw);
        if self.state.state() != State::Fault {
            self.error_code = 0;
        }
        let before = self.position;
        if self.state.state() == State::OperationEnabled {
            let k = 1.0 - (-2.0 * core::f64::consts::PI * self.bandwidth_hz * dt_s.max(0.0)).exp();
            self.position += (f64::from(self.target) - self.position) * k;
        }
        self.velocity = if dt_s > 0.0 {
            (self.position - before) / dt_s
        } else {
            0.0
        };
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
}
