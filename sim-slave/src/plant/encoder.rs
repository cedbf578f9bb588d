//! An incremental encoder terminal (in the manner of a Beckhoff EL5101): it counts the
//! quadrature edges of an *external* shaft — one the test turns, or that turns by itself at
//! a set speed — into a wrapping 32-bit counter the master reads, latches the counter at
//! the index pulse (input C) when asked, and lets the master set the counter.
//!
//! Process data (fixed PDOs in the EEPROM, no CoE; bit numbers are the EL5101's object
//! 0x6000/0x7000 sub-indices minus one):
//! outputs (RxPDO 0x1600) `0x7000 control: u16, 0x7000:11 set counter value: u32`;
//! inputs (TxPDO 0x1A00) `0x6000 status: u16, 0x6000:11 counter value: u32, 0x6000:12
//! latch value: u32`.
//!
//! Set counter works like the real terminal: a rising edge of control bit 2 loads the set
//! value; status bit 2 acknowledges it and stays set until the master clears bit 2. The
//! overflow/underflow bits follow the EL5101's rule: overflow is set when the counter wraps
//! from 0xFFFF_FFFF to 0 and cleared once it passes a third of the range or underflows;
//! underflow mirrors it.
//!
//! Like the EL5101, status bit 15 (0x6000:10 "TxPDO Toggle") toggles with every new
//! counter value the module publishes (here: every step), and bit 14 (0x6000:0F "TxPDO
//! State") is set while the data are invalid (an encoder fault: a broken wire, no supply).
//! A master watches both to know the encoder is alive. Fault injection: the error bit on or
//! off ([`EncoderModule::set_data_invalid`]) and a frozen module whose counter and toggle
//! stop updating ([`EncoderModule::set_frozen`]); an unreachable module is a chain fault
//! ([`crate::fault::Faults`]).

use super::Exchange;
use crate::esc::memory::Memory;

/// Encoder inputs object (status, counter value, latch value).
pub const ENC_INPUTS: u16 = 0x6000;
/// Encoder outputs object (control, set counter value).
pub const ENC_OUTPUTS: u16 = 0x7000;
/// Sub-index of the counter value in 0x6000.
pub const SUB_COUNTER_VALUE: u8 = 0x11;
/// Sub-index of the latch value in 0x6000.
pub const SUB_LATCH_VALUE: u8 = 0x12;
/// Sub-index of the set counter value in 0x7000.
pub const SUB_SET_COUNTER_VALUE: u8 = 0x11;

/// Bytes of the output process data.
pub const OUTPUT_BYTES: usize = 6;
/// Bytes of the input process data.
pub const INPUT_BYTES: usize = 10;

/// Control bits (0x7000).
pub mod control {
    /// 0x7000:01 enable latch C: latch the counter at the next index pulse.
    pub const ENABLE_LATCH_C: u16 = 1 << 0;
    /// 0x7000:03 set counter (rising edge loads the set counter value).
    pub const SET_COUNTER: u16 = 1 << 2;
}

/// Status bits (0x6000).
pub mod status {
    /// 0x6000:01 latch C valid: the latch value holds the counter at an index pulse.
    pub const LATCH_C_VALID: u16 = 1 << 0;
    /// 0x6000:03 set counter done.
    pub const SET_COUNTER_DONE: u16 = 1 << 2;
    /// 0x6000:04 counter underflow.
    pub const COUNTER_UNDERFLOW: u16 = 1 << 3;
    /// 0x6000:05 counter overflow.
    pub const COUNTER_OVERFLOW: u16 = 1 << 4;
    /// 0x6000:0B status of input C (the index track is high).
    pub const INPUT_C: u16 = 1 << 10;
    /// 0x6000:0F TxPDO State: the inputs are invalid (the encoder is faulted).
    pub const TXPDO_STATE: u16 = 1 << 14;
    /// 0x6000:10 TxPDO Toggle: toggles with each new value the module publishes.
    pub const TXPDO_TOGGLE: u16 = 1 << 15;
}

/// A third and two thirds of the counter range: where overflow and underflow flags clear.
const THIRD: u32 = 0x5555_5555;
const TWO_THIRDS: u32 = 0xAAAA_AAAA;

/// An encoder module.
#[derive(Clone, Debug)]
pub struct EncoderModule {
    /// Where the output process data lies in the ESC's RAM.
    pub outputs_at: u16,
    /// Where the input process data lies.
    pub inputs_at: u16,
    /// Encoder counts per shaft revolution (edges of A and B, ×4 decoded).
    pub counts_per_rev: u32,
    /// Speed at which the shaft turns by itself (rev/s), 0 when the test turns it.
    pub shaft_speed_rev_s: f64,
    /// Shaft position (counts, fractional): where the shaft is.
    shaft_counts: f64,
    /// Whole counts already passed to the counter.
    position_counts: i64,
    counter: u32,
    latch: u32,
    status: u16,
    last_control: u16,
    /// Injected: the encoder is faulted (TxPDO State set).
    data_invalid: bool,
    /// Injected: the module publishes nothing new (counter and toggle stand still).
    frozen: bool,
}

impl EncoderModule {
    /// A module on a shaft at 0 with the counter at 0.
    pub fn new(outputs_at: u16, inputs_at: u16, counts_per_rev: u32) -> Self {
        Self {
            outputs_at,
            inputs_at,
            counts_per_rev: counts_per_rev.max(1),
            shaft_speed_rev_s: 0.0,
            shaft_counts: 0.0,
            position_counts: 0,
            counter: 0,
            latch: 0,
            status: 0,
            last_control: 0,
            data_invalid: false,
            frozen: false,
        }
    }

    /// Sets the counter to `value` now, as a set-counter command would (the shaft stays
    /// where it is): e.g. near the wrap, for a test of the master's unwrapping.
    pub fn preset_counter(&mut self, value: u32) {
        self.counter = value;
    }

    /// Injects (or clears) an encoder fault: TxPDO State (status bit 14) is set while on.
    pub fn set_data_invalid(&mut self, on: bool) {
        self.data_invalid = on;
    }

    /// Freezes (or thaws) the module: while frozen its inputs are not updated (counter,
    /// status and the toggle stand still); the shaft still turns and is counted on thaw.
    pub fn set_frozen(&mut self, on: bool) {
        self.frozen = on;
    }

    /// Puts the shaft at `revs` revolutions (counted at the next step).
    pub fn set_shaft_position(&mut self, revs: f64) {
        if revs.is_finite() {
            self.shaft_counts = revs * f64::from(self.counts_per_rev);
        }
    }

    /// Turns the shaft at `rev_s` for `dt_s` seconds (counted at the next step).
    pub fn drive(&mut self, rev_s: f64, dt_s: f64) {
        let d = rev_s * dt_s * f64::from(self.counts_per_rev);
        if d.is_finite() {
            self.shaft_counts += d;
        }
    }

    /// The shaft's position in whole counts (what the counter has seen after a step).
    pub fn position_counts(&self) -> i64 {
        self.position_counts
    }

    /// The counter value.
    pub fn counter(&self) -> u32 {
        self.counter
    }

    /// The status word.
    pub fn status(&self) -> u16 {
        self.status
    }

    /// Whole counts of the shaft position.
    fn shaft_whole_counts(&self) -> i64 {
        self.shaft_counts
            .floor()
            .clamp(i64::MIN as f64, i64::MAX as f64) as i64
    }

    /// The first index position (a whole multiple of `counts_per_rev`) the shaft reached
    /// moving from `from` to `to`; the position it left does not count.
    fn first_index(&self, from: i64, to: i64) -> Option<i64> {
        let per_rev = i64::from(self.counts_per_rev);
        let index = if to > from {
            from.div_euclid(per_rev)
                .saturating_add(1)
                .saturating_mul(per_rev)
        } else if to < from {
            // The largest multiple below `from`.
            (from.saturating_sub(1))
                .div_euclid(per_rev)
                .saturating_mul(per_rev)
        } else {
            return None;
        };
        (index >= from.min(to) && index <= from.max(to)).then_some(index)
    }

    /// Counts the shaft's motion since the last step into the counter.
    fn count(&mut self, control: u16) {
        let to = self.shaft_whole_counts();
        let from = self.position_counts;
        let delta = to.saturating_sub(from);
        let raw = i128::from(self.counter) + i128::from(delta);
        if raw > i128::from(u32::MAX) {
            self.status = (self.status | status::COUNTER_OVERFLOW) & !status::COUNTER_UNDERFLOW;
        } else if raw < 0 {
            self.status = (self.status | status::COUNTER_UNDERFLOW) & !status::COUNTER_OVERFLOW;
        }
        // The counter is the low 32 bits of the count, as a hardware counter wraps.
        let new_counter = self.counter.wrapping_add(delta as u32);
        if control & control::ENABLE_LATCH_C != 0 && self.status & status::LATCH_C_VALID == 0 {
            if let Some(index) = self.first_index(from, to) {
                self.latch = self.counter.wrapping_add(index.wrapping_sub(from) as u32);
                self.status |= status::LATCH_C_VALID;
            }
        }
        self.counter = new_counter;
        self.position_counts = to;
        if self.status & status::COUNTER_OVERFLOW != 0 && self.counter > THIRD {
            self.status &= !status::COUNTER_OVERFLOW;
        }
        if self.status & status::COUNTER_UNDERFLOW != 0 && self.counter < TWO_THIRDS {
            self.status &= !status::COUNTER_UNDERFLOW;
        }
        let on_index = self
            .position_counts
            .rem_euclid(i64::from(self.counts_per_rev))
            == 0;
        if on_index {
            self.status |= status::INPUT_C;
        } else {
            self.status &= !status::INPUT_C;
        }
    }

    /// One cycle: turn the shaft (if it turns by itself), count, act on the control word,
    /// write inputs, as far as `exchange` allows (the shaft turns and the counter counts
    /// in every state; outside Op the control word is its safe state, zero).
    pub fn step(&mut self, mem: &mut Memory, dt_s: f64, exchange: Exchange) {
        let mut out = [0u8; OUTPUT_BYTES];
        if exchange.outputs {
            mem.ecat_read(self.outputs_at, &mut out, false);
        }
        let control = u16::from_le_bytes([out[0], out[1]]);
        let set_value = u32::from_le_bytes([out[2], out[3], out[4], out[5]]);
        if self.shaft_speed_rev_s != 0.0 {
            self.drive(self.shaft_speed_rev_s, dt_s);
        }
        if self.frozen {
            // Nothing new is published: the last inputs stay in the process data.
            return;
        }
        self.count(control);
        // Latch C is re-armed by clearing the enable bit.
        if control & control::ENABLE_LATCH_C == 0 {
            self.status &= !status::LATCH_C_VALID;
        }
        let rising = control & !self.last_control & control::SET_COUNTER != 0;
        if rising {
            self.counter = set_value;
            self.status |= status::SET_COUNTER_DONE;
            self.status &= !(status::COUNTER_OVERFLOW | status::COUNTER_UNDERFLOW);
        } else if control & control::SET_COUNTER == 0 {
            self.status &= !status::SET_COUNTER_DONE;
        }
        self.last_control = control;
        if self.data_invalid {
            self.status |= status::TXPDO_STATE;
        } else {
            self.status &= !status::TXPDO_STATE;
        }
        // A new value each step.
        self.status ^= status::TXPDO_TOGGLE;
        let mut inp = [0u8; INPUT_BYTES];
        inp[0..2].copy_from_slice(&self.status.to_le_bytes());
        inp[2..6].copy_from_slice(&self.counter.to_le_bytes());
        inp[6..10].copy_from_slice(&self.latch.to_le_bytes());
        if exchange.inputs {
            mem.pdi_write(self.inputs_at, &inp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::esc::registers::PROCESS_RAM;

    const OUT: u16 = PROCESS_RAM;
    const IN: u16 = PROCESS_RAM + 0x100;

    fn module() -> (Memory, EncoderModule) {
        (Memory::new(), EncoderModule::new(OUT, IN, 4096))
    }

    fn outputs(mem: &mut Memory, control: u16, set_value: u32) {
        let mut b = [0u8; OUTPUT_BYTES];
        b[0..2].copy_from_slice(&control.to_le_bytes());
        b[2..6].copy_from_slice(&set_value.to_le_bytes());
        mem.pdi_write(OUT, &b);
    }

    /// (status, counter, latch) as the master reads them.
    fn inputs(mem: &Memory) -> (u16, u32, u32) {
        let mut b = [0u8; INPUT_BYTES];
        mem.ecat_read(IN, &mut b, false);
        (
            u16::from_le_bytes([b[0], b[1]]),
            u32::from_le_bytes([b[2], b[3], b[4], b[5]]),
            u32::from_le_bytes([b[6], b[7], b[8], b[9]]),
        )
    }

    #[test]
    fn outputs_count_only_in_op_and_inputs_from_safeop_on() {
        use crate::esc::al::AlState;
        let (mut mem, mut e) = module();
        e.set_shaft_position(1.0);
        // Init: the counter counts, nothing is published.
        e.step(&mut mem, 0.001, Exchange::in_state(AlState::Init));
        assert_eq!(inputs(&mem), (0, 0, 0));
        // SafeOp: published; the master's "set counter" is not taken (safe outputs).
        outputs(&mut mem, control::SET_COUNTER, 7);
        e.step(&mut mem, 0.001, Exchange::in_state(AlState::SafeOp));
        assert_eq!(inputs(&mem).1, 4096);
        assert_eq!(inputs(&mem).0 & status::SET_COUNTER_DONE, 0);
        // Op: taken.
        e.step(&mut mem, 0.001, Exchange::in_state(AlState::Op));
        assert_eq!(inputs(&mem).1, 7);
        assert_ne!(inputs(&mem).0 & status::SET_COUNTER_DONE, 0);
    }

    #[test]
    fn counts_the_shaft_in_whole_counts_both_ways() {
        let (mut mem, mut e) = module();
        e.set_shaft_position(2.5);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).1, 10_240);
        // 1 rev/s for 1 ms at 4096 counts/rev: 4.096 counts, floor of the shaft position.
        e.drive(1.0, 0.001);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).1, 10_244);
        e.drive(1.0, 0.001);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).1, 10_248, "10 248.192: the fraction is kept");
        e.set_shaft_position(-1.0);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).1, (-4096i32) as u32);
        assert_eq!(e.position_counts(), -4096);
    }

    #[test]
    fn a_shaft_turning_by_itself_is_counted_each_step() {
        let (mut mem, mut e) = module();
        e.shaft_speed_rev_s = 0.5;
        for _ in 0..1000 {
            e.step(&mut mem, 0.001, Exchange::OP);
        }
        // 0.5 rev in 1000 steps of 2.048 counts: 2048 up to rounding of the sum.
        assert!(
            (2047..=2048).contains(&inputs(&mem).1),
            "{:?}",
            inputs(&mem)
        );
    }

    #[test]
    fn the_counter_wraps_and_flags_underflow_and_overflow() {
        let (mut mem, mut e) = module();
        e.set_shaft_position(-1.0 / 4096.0);
        e.step(&mut mem, 0.001, Exchange::OP);
        let (st, c, _) = inputs(&mem);
        assert_eq!(c, u32::MAX, "0 − 1 wraps to 0xFFFF_FFFF");
        assert_ne!(st & status::COUNTER_UNDERFLOW, 0);
        assert_eq!(st & status::COUNTER_OVERFLOW, 0);
        // Back over 0: overflow, which clears underflow.
        e.set_shaft_position(1.0);
        e.step(&mut mem, 0.001, Exchange::OP);
        let (st, c, _) = inputs(&mem);
        assert_eq!(c, 4096);
        assert_eq!(
            st & (status::COUNTER_OVERFLOW | status::COUNTER_UNDERFLOW),
            status::COUNTER_OVERFLOW
        );
        // Past a third of the range the overflow flag clears.
        e.set_shaft_position(f64::from(THIRD) / 4096.0 + 1.0);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).0 & status::COUNTER_OVERFLOW, 0);
    }

    #[test]
    fn set_counter_loads_on_the_rising_edge_and_is_acknowledged() {
        let (mut mem, mut e) = module();
        e.set_shaft_position(1.0);
        outputs(&mut mem, 0, 1_000_000);
        e.step(&mut mem, 0.001, Exchange::OP);
        let (st, c, latch) = inputs(&mem);
        assert_eq!(
            (st & !status::TXPDO_TOGGLE, c, latch),
            (status::INPUT_C, 4096, 0)
        );
        outputs(&mut mem, control::SET_COUNTER, 1_000_000);
        e.step(&mut mem, 0.001, Exchange::OP);
        let (st, c, _) = inputs(&mem);
        assert_eq!(c, 1_000_000);
        assert_ne!(st & status::SET_COUNTER_DONE, 0);
        // Held high: counting goes on from the set value, the value is not loaded again.
        e.set_shaft_position(1.5);
        outputs(&mut mem, control::SET_COUNTER, 7);
        e.step(&mut mem, 0.001, Exchange::OP);
        let (st, c, _) = inputs(&mem);
        assert_eq!(c, 1_002_048);
        assert_ne!(st & status::SET_COUNTER_DONE, 0);
        // Cleared: the acknowledgement goes.
        outputs(&mut mem, 0, 7);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).0 & status::SET_COUNTER_DONE, 0);
        assert_eq!(inputs(&mem).1, 1_002_048);
    }

    #[test]
    fn latch_c_holds_the_counter_at_the_index_pulse() {
        let (mut mem, mut e) = module();
        e.set_shaft_position(0.75);
        e.step(&mut mem, 0.001, Exchange::OP);
        outputs(&mut mem, control::ENABLE_LATCH_C, 0);
        // 3072 → 5000 passes the index at 4096.
        e.set_shaft_position(5000.0 / 4096.0);
        e.step(&mut mem, 0.001, Exchange::OP);
        let (st, c, latch) = inputs(&mem);
        assert_eq!((c, latch), (5000, 4096));
        assert_ne!(st & status::LATCH_C_VALID, 0);
        // Latched once: the next index does not overwrite it.
        e.set_shaft_position(2.5);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).2, 4096);
        // Re-armed, backwards from 10 240 passes 8192.
        outputs(&mut mem, 0, 0);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).0 & status::LATCH_C_VALID, 0);
        outputs(&mut mem, control::ENABLE_LATCH_C, 0);
        e.set_shaft_position(1.9);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).2, 8192);
        assert_ne!(inputs(&mem).0 & status::LATCH_C_VALID, 0);
    }

    #[test]
    fn the_txpdo_toggle_flips_with_every_new_value() {
        let (mut mem, mut e) = module();
        let mut last = None;
        for _ in 0..6 {
            e.step(&mut mem, 0.001, Exchange::OP);
            let toggle = inputs(&mem).0 & status::TXPDO_TOGGLE != 0;
            assert_ne!(Some(toggle), last, "toggled");
            last = Some(toggle);
        }
    }

    #[test]
    fn the_txpdo_state_bit_follows_the_injected_encoder_fault() {
        let (mut mem, mut e) = module();
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).0 & status::TXPDO_STATE, 0);
        e.set_data_invalid(true);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_ne!(inputs(&mem).0 & status::TXPDO_STATE, 0);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_ne!(inputs(&mem).0 & status::TXPDO_STATE, 0, "held while on");
        e.set_data_invalid(false);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).0 & status::TXPDO_STATE, 0);
    }

    #[test]
    fn a_frozen_module_publishes_nothing_new_and_counts_the_shaft_on_thaw() {
        let (mut mem, mut e) = module();
        e.shaft_speed_rev_s = 1.0;
        e.step(&mut mem, 0.001, Exchange::OP);
        let before = inputs(&mem);
        e.set_frozen(true);
        for _ in 0..5 {
            e.step(&mut mem, 0.001, Exchange::OP);
            assert_eq!(
                inputs(&mem),
                before,
                "counter, status and toggle stand still"
            );
        }
        e.set_frozen(false);
        e.step(&mut mem, 0.001, Exchange::OP);
        let (st, c, _) = inputs(&mem);
        // Six steps of 4.096 counts since the first: 4 + 6 · 4.096 = 28.576 → 28.
        assert_eq!(c, 28);
        assert_ne!(st & status::TXPDO_TOGGLE, before.0 & status::TXPDO_TOGGLE);
    }

    #[test]
    fn a_preset_counter_counts_on_through_the_wrap() {
        let (mut mem, mut e) = module();
        e.preset_counter(0xFFFF_FFF0);
        e.set_shaft_position(32.0 / 4096.0);
        e.step(&mut mem, 0.001, Exchange::OP);
        assert_eq!(inputs(&mem).1, 0x10, "0xFFFF_FFF0 + 32 wraps to 0x10");
    }
}
