//! An external axis' encoder input (seed 000 §2.4, §5.5): the counter of an incremental
//! encoder module (an EL5101-like terminal: 0x6000 status u16, then 0x6000:11 counter value
//! u32 in its TxPDO) turned into the axis' actual position and velocity each cycle, and
//! the module watched so that a lost encoder stops the axes that follow it (seed 001: "when
//! the master is unavailable, e.g. the encoder disconnected or not working, the followers
//! go to ErrorStop").
//!
//! The 32-bit counter wraps; it is extended to an exact 64-bit count
//! ([`CountExtender`]: the first value read is taken as a signed 32-bit count, as a
//! drive's position actual value is). The velocity is the count difference over the
//! cycles since the last value. The axis is lost, with a code per reason, when
//! - the bus cannot reach the module ([`COMMUNICATION_FAULT`], the drives' path),
//! - the module says its data are invalid (status bit 14, "TxPDO State":
//!   [`ENCODER_DATA_INVALID`]),
//! - its "TxPDO Toggle" (status bit 15, flipped with every new value) has not changed
//!   for the freeze timeout ([`ENCODER_FROZEN`]).
//!
//! While lost the axis keeps its last good position (no jump) and a velocity of 0; once
//! the module is good again the count goes on from the module's counter (the shaft
//! turned meanwhile: the position is where the shaft is). Nothing here allocates.

use gantry_drives::scaling::{CountExtender, ModuloCounts, Scaling, ScalingError};
use gantry_kernel::axis::AxisFeedback;

use super::cycle::COMMUNICATION_FAULT;

/// Error code of an external axis whose encoder module reports its data invalid (EL5101
/// 0x6000:0F TxPDO State): CiA 301 emergency class 0x73xx, "additional modules: sensor" —
/// the module is reachable and says its encoder failed.
pub const ENCODER_DATA_INVALID: u16 = 0x7300;

/// Error code of an external axis whose encoder module publishes nothing new (its TxPDO
/// Toggle stood still past the freeze timeout): CiA 301 0x8130, "life guard error" — the
/// toggle is the module's life sign per value; the bus still reaches the module (that
/// would be [`COMMUNICATION_FAULT`]), but its firmware has stopped producing values.
pub const ENCODER_FROZEN: u16 = 0x8130;

/// Status bit 14 of 0x6000 (0x6000:0F TxPDO State): the inputs are invalid.
pub const STATUS_TXPDO_STATE: u16 = 1 << 14;

/// What an encoder-loss code means, for the status and the CLI.
pub const fn describe(code: u16) -> &'static str {
    match code {
        ENCODER_DATA_INVALID => "the module flags its encoder data invalid (TxPDO State)",
        ENCODER_FROZEN => "the module's values stopped changing (TxPDO Toggle frozen)",
        crate::runtime::cycle::COMMUNICATION_FAULT => "the module is unreachable on the bus",
        _ => "unknown encoder fault",
    }
}
/// Status bit 15 of 0x6000 (0x6000:10 TxPDO Toggle): toggles with each new value.
pub const STATUS_TXPDO_TOGGLE: u16 = 1 << 15;

/// Input bytes the encoder input reads: status (u16), counter value (u32).
pub const INPUT_BYTES: usize = 6;

/// One external axis' encoder module, as the cycle reads it.
#[derive(Clone, Copy, Debug)]
pub struct EncoderInput {
    /// EtherCAT position of the module.
    pub slave: usize,
    scaling: Scaling,
    modulo: Option<ModuloCounts>,
    counts: CountExtender,
    cycle_s: f64,
    /// Cycles without a toggle before the module is frozen.
    freeze_cycles: u32,
    /// Cycles since the toggle last changed (or since the first value).
    since_toggle: u32,
    /// The toggle bit last seen; `None` before the first value (and after a loss of the
    /// module: its toggle is watched afresh).
    toggle: Option<bool>,
    /// The last good count and the cycles since it was read.
    last_count: Option<i64>,
    since_count: u32,
    feedback: AxisFeedback,
}

impl EncoderInput {
    /// The encoder input of module `slave`, its counts in units by `scaling` (wrapping at
    /// `modulo` units), lost after `freeze_timeout_ms` without a new value, read every
    /// `cycle_s` seconds.
    pub fn new(
        slave: usize,
        scaling: Scaling,
        modulo: Option<f64>,
        freeze_timeout_ms: f64,
        cycle_s: f64,
    ) -> Result<Self, ScalingError> {
        let modulo = modulo.map(|p| ModuloCounts::new(scaling, p)).transpose()?;
        let cycles = (freeze_timeout_ms * 1e-3 / cycle_s).floor();
        // The cast saturates; at least one cycle.
        let freeze_cycles = (cycles as u32).max(1);
        Ok(Self {
            slave,
            scaling,
            modulo,
            counts: CountExtender::new(),
            cycle_s,
            freeze_cycles,
            since_toggle: 0,
            toggle: None,
            last_count: None,
            since_count: 0,
            feedback: AxisFeedback::default(),
        })
    }

    /// The extended count last read (`None` before the first good value).
    pub fn count(&self) -> Option<i64> {
        self.last_count
    }

    /// The axis' feedback as of the last [`EncoderInput::read`].
    pub fn feedback(&self) -> &AxisFeedback {
        &self.feedback
    }

    /// One cycle. `unreachable`: the bus cannot reach the module; `inputs`: its input
    /// bytes when new ones came with the last exchange (`None`: nothing new, a lost
    /// frame — time passes for the freeze watch, the position is kept).
    pub fn read(&mut self, unreachable: bool, inputs: Option<&[u8]>) -> &AxisFeedback {
        self.since_count = self.since_count.saturating_add(1);
        if unreachable {
            self.toggle = None;
            self.since_toggle = 0;
            return self.lost(COMMUNICATION_FAULT);
        }
        let Some(bytes) = inputs else {
            self.since_toggle = self.since_toggle.saturating_add(1);
            if self.toggle.is_some() && self.since_toggle > self.freeze_cycles {
                return self.lost(ENCODER_FROZEN);
            }
            return &self.feedback;
        };
        let (Some(status), Some(counter)) = (
            bytes
                .get(0..2)
                .and_then(|b| b.try_into().ok())
                .map(u16::from_le_bytes),
            bytes
                .get(2..6)
                .and_then(|b| b.try_into().ok())
                .map(u32::from_le_bytes),
        ) else {
            // Checked when the cycle is built: cannot happen on a bus that keeps its image.
            return self.lost(COMMUNICATION_FAULT);
        };
        let toggle = status & STATUS_TXPDO_TOGGLE != 0;
        if self.toggle == Some(toggle) {
            self.since_toggle = self.since_toggle.saturating_add(1);
        } else {
            self.since_toggle = 0;
        }
        self.toggle = Some(toggle);
        if status & STATUS_TXPDO_STATE != 0 {
            return self.lost(ENCODER_DATA_INVALID);
        }
        if self.since_toggle > self.freeze_cycles {
            return self.lost(ENCODER_FROZEN);
        }
        // The counter's bits as a signed 32-bit count (a drive's position actual value).
        let count = self
            .counts
            .update(i32::from_le_bytes(counter.to_le_bytes()));
        let velocity = match self.last_count {
            Some(last) if self.since_count > 0 => {
                let counts_per_s = (count.saturating_sub(last)) as f64
                    / (f64::from(self.since_count) * self.cycle_s);
                self.scaling.velocity_to_units(counts_per_s)
            }
            _ => 0.0,
        };
        self.last_count = Some(count);
        self.since_count = 0;
        self.feedback = AxisFeedback {
            position: self.position(count),
            velocity,
            operation_enabled: false,
            fault: None,
            ..AxisFeedback::default()
        };
        &self.feedback
    }

    /// The axis position (units) of `count`: within the period on a modulo axis.
    fn position(&self, count: i64) -> f64 {
        match &self.modulo {
            Some(mc) => mc.to_position(count).1,
            None => self.scaling.counts_to_units(count),
        }
    }

    /// Lost with `code`: the last good position, standing.
    fn lost(&mut self, code: u16) -> &AxisFeedback {
        self.feedback.velocity = 0.0;
        self.feedback.fault = Some(code);
        &self.feedback
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::scaling::ScalingConfig;

    /// 4096 counts per unit.
    fn input(modulo: Option<f64>) -> EncoderInput {
        let scaling = Scaling::new(ScalingConfig {
            counts_per_motor_rev: 4096,
            motor_revs: 1,
            load_revs: 1,
            units_per_load_rev: 1.0,
            invert: false,
        })
        .unwrap();
        EncoderInput::new(3, scaling, modulo, 5.0, 1e-3).unwrap()
    }

    fn bytes(status: u16, counter: u32) -> [u8; 6] {
        let mut b = [0u8; 6];
        b[0..2].copy_from_slice(&status.to_le_bytes());
        b[2..6].copy_from_slice(&counter.to_le_bytes());
        b
    }

    #[test]
    fn counts_through_the_32_bit_wrap_exactly_with_the_velocity() {
        let mut e = input(None);
        let mut counter = 0xFFFF_FF00u32;
        let mut toggle = 0;
        for k in 0..1000i64 {
            toggle ^= STATUS_TXPDO_TOGGLE;
            let fb = *e.read(false, Some(&bytes(toggle, counter)));
            assert_eq!(fb.fault, None);
            // The first value is −256 (signed), then 41 counts a cycle.
            assert_eq!(e.count(), Some(-256 + 41 * k));
            assert_eq!(fb.position, (-256 + 41 * k) as f64 / 4096.0);
            if k > 0 {
                assert!((fb.velocity - 41.0 / 4096.0 / 1e-3).abs() < 1e-9);
            }
            counter = counter.wrapping_add(41);
        }
    }

    #[test]
    fn a_modulo_axis_reads_within_its_period() {
        let mut e = input(Some(1.0));
        let fb = *e.read(false, Some(&bytes(0, 4096 * 3 + 1024)));
        assert_eq!(fb.position, 0.25);
    }

    #[test]
    fn each_loss_has_its_code_and_keeps_the_last_good_position() {
        let mut e = input(None);
        let mut toggle = 0;
        let good = |e: &mut EncoderInput, toggle: &mut u16, counter: u32| {
            *toggle ^= STATUS_TXPDO_TOGGLE;
            *e.read(false, Some(&bytes(*toggle, counter)))
        };
        assert_eq!(good(&mut e, &mut toggle, 4096).position, 1.0);
        // Data invalid: the counter it sends is not taken.
        toggle ^= STATUS_TXPDO_TOGGLE;
        let fb = *e.read(false, Some(&bytes(toggle | STATUS_TXPDO_STATE, 99_999)));
        assert_eq!((fb.fault, fb.position), (Some(ENCODER_DATA_INVALID), 1.0));
        assert_eq!(good(&mut e, &mut toggle, 8192).fault, None);
        // Frozen: 5 ms at 1 ms, the sixth cycle without a toggle is the loss.
        let frozen = bytes(toggle, 8192);
        for _ in 0..5 {
            assert_eq!(e.read(false, Some(&frozen)).fault, None);
        }
        let fb = *e.read(false, Some(&frozen));
        assert_eq!((fb.fault, fb.position), (Some(ENCODER_FROZEN), 2.0));
        // Lost frames count as time without a new value too.
        assert_eq!(good(&mut e, &mut toggle, 8192).fault, None);
        for _ in 0..5 {
            assert_eq!(e.read(false, None).fault, None);
        }
        assert_eq!(e.read(false, None).fault, Some(ENCODER_FROZEN));
        // Unreachable.
        let fb = *e.read(true, None);
        assert_eq!((fb.fault, fb.position), (Some(COMMUNICATION_FAULT), 2.0));
        // Back: the first value is good again, the toggle watched afresh.
        let fb = good(&mut e, &mut toggle, 12_288);
        assert_eq!((fb.fault, fb.position), (None, 3.0));
    }
}
