//! The master side of one CSP drive: power state machine steps, counts, modulo periods.

use thiserror::Error;

use crate::cia402::controlword::Command;
use crate::cia402::pdo::PdoLayout;
use crate::cia402::procedure::{ProcedureOutputs, MODE_BITS};
use crate::cia402::{next_command, Controlword, State, Target};
use crate::scaling::{CountExtender, ModuloCounts, Scaling, ScalingError};

use super::probe::{DriveSwitches, ProbeArming, ProbeTarget, SwitchWiring};
use super::{CspInputs, CspOffsets, LayoutError, COUNT_RANGE_FAULT, FAULT_CODE_NOT_MAPPED};
use crate::cia402::objects;

/// Set values of one axis for its drive (user units; the kernel's set values, as plain
/// data).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CspSetpoint {
    /// Set position (units; within the period on modulo axes).
    pub position: f64,
    /// Whole modulo periods of that position, so the channel can count `turns · period +
    /// position` exactly (0 on normal axes).
    pub turns: i64,
    /// Whether the drive should be enabled.
    pub enable: bool,
    /// Send a fault reset (the axis' Reset asks for it).
    pub reset_fault: bool,
    /// Which switch the touch probe latches (a homing run on a limit switch's edge asks
    /// for that limit switch).
    pub probe: ProbeTarget,
}

/// Actual values of one drive in user units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CspFeedback {
    /// Actual position (units; within the period on modulo axes).
    pub position: f64,
    /// Actual velocity (units/s; 0 when 0x606C is not mapped).
    pub velocity: f64,
    /// The drive is in Operation enabled.
    pub operation_enabled: bool,
    /// The drive reports a fault with this error code, or the channel faults the axis
    /// ([`COUNT_RANGE_FAULT`]).
    pub fault: Option<u16>,
    /// The limit and home switches from 0x60FD (all inactive where not wired).
    pub switches: DriveSwitches,
    /// Positions the touch probes latched this cycle (units, like `position`).
    pub latches: CspLatches,
}

/// Positions a drive's touch probes latched, new this cycle (units).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CspLatches {
    /// The home switch became active here.
    pub rising: Option<f64>,
    /// The home switch became inactive here.
    pub falling: Option<f64>,
    /// The index pulse passed here.
    pub index: Option<f64>,
}

/// The master side of one drive.
#[derive(Clone, Debug)]
pub struct CspChannel {
    /// Units ⇄ counts of the axis on this drive.
    pub scaling: Scaling,
    /// Where the objects sit in the drive's process data.
    pub offsets: CspOffsets,
    /// Whole periods ⇄ counts on a modulo axis.
    modulo: Option<ModuloCounts>,
    last_cw: Controlword,
    /// The drive's 32-bit position actual value, extended. Fresh with the channel (the bus
    /// brought up), and deliberately not reset when a lost slave comes back: a drive
    /// that kept its power kept counting, and extending by the difference to the last
    /// value seen is right for any motion under 2³¹ counts while it was unseen, where
    /// starting over would move a linear axis past ±2³¹ by 2³² counts. A modulo axis is
    /// aligned again when it is next enabled either way.
    extender: CountExtender,
    /// The extended position actual value of the last inputs (counts).
    actual: i64,
    /// Modulo axes: whole periods of the drive's counter at `actual`.
    actual_turns: i64,
    /// Modulo axes: the drive's periods minus the set values', fixed while the drive is
    /// driven (taken at the cycle it is enabled).
    turn_offset: i64,
    /// The drive took set positions last cycle.
    driving: bool,
    /// The last target sent (64-bit counts).
    last_target: i64,
    /// The last set position had no 64-bit count: the axis faults.
    count_error: Option<CountError>,
    /// The axis' modulo period cannot be counted (see [`CspChannel::set_modulo_period`]): the
    /// drive is never driven and the axis faults.
    unusable: Option<ScalingError>,
    /// Which 0x60FD bits are switches, and their polarity.
    wiring: SwitchWiring,
    /// The touch probes' arming (used where the layout maps 0x60B8 and 0x60B9).
    probe: ProbeArming,
}

/// A set position with no 64-bit count.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
#[error("set position {position} (+ {turns} periods) has no 64-bit drive count")]
pub struct CountError {
    /// Position (units; within the period on modulo axes).
    pub position: f64,
    /// Whole periods in the drive's count space (0 on normal axes).
    pub turns: i64,
}

impl CspChannel {
    /// A channel with the axis' scaling, for a drive with its power-up mapping.
    pub fn new(scaling: Scaling) -> Self {
        Self {
            scaling,
            offsets: CspOffsets::minimal(),
            modulo: None,
            last_cw: Controlword(0),
            extender: CountExtender::new(),
            actual: 0,
            actual_turns: 0,
            turn_offset: 0,
            driving: false,
            last_target: 0,
            count_error: None,
            unusable: None,
            wiring: SwitchWiring::default(),
            probe: ProbeArming::default(),
        }
    }

    /// Reads the limit and home switches from 0x60FD as `wiring` says.
    pub fn set_switch_wiring(&mut self, wiring: SwitchWiring) {
        self.wiring = wiring;
    }

    /// 0x60B8 for this cycle's outputs, where the layout maps it (arms the probes; see
    /// [`super::probe`]).
    pub fn probe_function(&self) -> Option<u16> {
        self.offsets
            .map()
            .output_offset(objects::TOUCH_PROBE_FUNCTION)
            .map(|_| self.probe.function())
    }

    /// A drive position (32-bit counts, latched near the last actual value) in units.
    fn latch_units(&self, counts: i32) -> f64 {
        let near = self.actual as i32;
        let counts = self.actual + i64::from(counts.wrapping_sub(near));
        match self.modulo {
            Some(mc) => mc.to_position(counts).1,
            None => self.scaling.counts_to_units(counts),
        }
    }

    /// A channel for a drive mapped to `layout`.
    pub fn with_layout(scaling: Scaling, layout: &PdoLayout) -> Result<Self, LayoutError> {
        Ok(Self {
            offsets: CspOffsets::of(layout)?,
            ..Self::new(scaling)
        })
    }

    /// Makes the channel count a modulo axis of `period` units (`None`: a normal axis; the
    /// period as a plain number, see [`ModuloCounts::new`]). Fails when the period is not
    /// a finite number > 0, is less than one count, or its count ratio does not fit 126
    /// bits.
    /// A channel that failed stays unusable (its axis faults with
    /// [`COUNT_RANGE_FAULT`] and its drive is not driven) until a call succeeds: counting
    /// a modulo axis as a normal one would step a period at every wrap.
    pub fn set_modulo_period(&mut self, period: Option<f64>) -> Result<(), ScalingError> {
        match period
            .map(|p| ModuloCounts::new(self.scaling, p))
            .transpose()
        {
            Ok(mc) => {
                self.modulo = mc;
                self.unusable = None;
                Ok(())
            }
            Err(e) => {
                self.unusable = Some(e);
                Err(e)
            }
        }
    }

    /// Why the channel cannot drive its axis at all, if it cannot.
    pub fn unusable(&self) -> Option<ScalingError> {
        self.unusable
    }

    /// The modulo period the channel counts (units), if any.
    pub fn modulo_period(&self) -> Option<f64> {
        self.modulo.map(|m| m.period())
    }

    /// The extended position actual value of the last inputs (64-bit counts).
    pub fn actual_counts(&self) -> i64 {
        self.actual
    }

    /// Where the drive was last sent (units, as [`CspChannel::drive_feedback`] gives
    /// positions: within the period on modulo axes): its actual position while it was
    /// not driven. A drive the master cannot see is still enabled and taking the frames
    /// it sends as far as the master knows, so this is where it stands once it stopped;
    /// its last position actual value is older, by the frames lost, and a set value taken
    /// from it would step the target back along the whole path travelled since.
    pub fn last_target_position(&self) -> f64 {
        match self.modulo {
            Some(mc) => mc.to_position(self.last_target).1,
            None => self.scaling.counts_to_units(self.last_target),
        }
    }

    /// Why the last set position was not sent, if it was not.
    pub fn count_error(&self) -> Option<CountError> {
        self.count_error
    }

    /// Decodes this drive's inputs; `None` when there are fewer bytes than its layout
    /// maps ([`CspInputs::decode`] says how many).
    pub fn decode(&self, bytes: &[u8]) -> Option<CspInputs> {
        CspInputs::decode(&self.offsets, bytes).ok()
    }

    /// Feedback from the drive's inputs; extends the position actual value.
    pub fn drive_feedback(&mut self, inputs: &CspInputs) -> CspFeedback {
        let state = inputs.statusword.state();
        self.actual = self.extender.update(inputs.position);
        let position = match self.modulo {
            Some(mc) => {
                let (turns, within) = mc.to_position(self.actual);
                self.actual_turns = turns;
                within
            }
            None => self.scaling.counts_to_units(self.actual),
        };
        let drive_fault = matches!(state, Some(State::Fault | State::FaultReactionActive))
            .then_some(
                inputs
                    .error_code
                    .filter(|c| *c != 0)
                    .unwrap_or(FAULT_CODE_NOT_MAPPED),
            );
        let new = match inputs.probe {
            Some(p) if self.probe_function().is_some() => self.probe.update(&p),
            _ => Default::default(),
        };
        let latches = CspLatches {
            rising: new.rising.map(|c| self.latch_units(c)),
            falling: new.falling.map(|c| self.latch_units(c)),
            index: new.index.map(|c| self.latch_units(c)),
        };
        CspFeedback {
            switches: self.wiring.read(inputs.digital_inputs.unwrap_or(0)),
            latches,
            position,
            velocity: inputs.velocity.map_or(0.0, |v| {
                self.scaling.counts_to_units(i64::from(v)) - self.scaling.counts_to_units(0)
            }),
            operation_enabled: state == Some(State::OperationEnabled),
            fault: drive_fault.or((self.count_error.is_some() || self.unusable.is_some())
                .then_some(COUNT_RANGE_FAULT)),
        }
    }

    /// The drive's count of `sp` (64 bits), in the drive's count space.
    fn target_counts(&self, sp: &CspSetpoint) -> Result<i64, CountError> {
        let turns = sp.turns.checked_add(self.turn_offset);
        let err = CountError {
            position: sp.position,
            turns: turns.unwrap_or(sp.turns),
        };
        match self.modulo {
            Some(mc) => mc
                .try_to_counts(turns.ok_or(err)?, sp.position)
                .map_err(|_| err),
            None => self
                .scaling
                .try_units_to_counts(sp.position)
                .map_err(|_| err),
        }
    }

    /// Modulo axes: the periods between the set values' frame and the drive's counter, so
    /// that `sp` counts to where the drive stands (the nearest period: `sp` and the
    /// actual differ by far less than half a period when the drive is taken over).
    fn align(&mut self, sp: &CspSetpoint) {
        let Some(mc) = self.modulo else { return };
        let (_, within) = mc.to_position(self.actual);
        let period = mc.period();
        let fraction = ((within - sp.position) / period).round();
        // `fraction` is −1, 0 or 1 (both positions lie in one period); NaN gives 0.
        self.turn_offset = self
            .actual_turns
            .saturating_sub(sp.turns)
            .saturating_add(fraction as i64);
    }

    /// The outputs for this cycle: one step of the power state machine towards what the
    /// set values want, and the target — the set position in the drive's counts while the
    /// drive is enabled, its actual position otherwise, so that enabling never jumps. The
    /// target is the low 32 bits of the 64-bit count (the drive's counter wraps).
    pub fn drive_outputs(&mut self, sp: &CspSetpoint, inputs: &CspInputs) -> (Controlword, i32) {
        self.probe.set_target(sp.probe);
        let state = inputs
            .statusword
            .state()
            .unwrap_or(State::NotReadyToSwitchOn);
        let target = if sp.enable {
            Target::Enabled
        } else {
            Target::Disabled
        };
        // Fault resets are sent only when the axis asks (its Reset).
        let cmd = next_command(state, target, sp.reset_fault, self.last_cw);
        self.last_cw = Controlword::of(cmd);
        if !(state == State::OperationEnabled && sp.enable) || self.unusable.is_some() {
            self.driving = false;
            self.count_error = None;
            self.last_target = self.actual;
            return (self.last_cw, inputs.position);
        }
        if !self.driving {
            // Taken over this cycle: the set position is where the drive stands.
            self.align(sp);
            self.driving = true;
            self.last_target = self.actual;
        }
        match self.target_counts(sp) {
            Ok(counts) => {
                self.count_error = None;
                self.last_target = counts;
            }
            Err(e) => self.count_error = Some(e),
        }
        // The low half, as the drive counts (its counter wraps, see the module doc).
        (self.last_cw, self.last_target as i32)
    }
}

impl CspChannel {
    /// The outputs for a cycle in which the drive is lent to a procedure
    /// ([`crate::cia402::procedure`]): one step of the power state machine towards
    /// Operation enabled with the procedure's mode-specific bits, and the drive's own
    /// actual position as the target (ignored outside CSP; a drive that switches back to
    /// CSP finds it where it stands). The channel lets go of the drive: when the
    /// procedure ends, it takes the drive over again as at enabling (the first CSP target
    /// is the set position the kernel tracked the drive with, its actual position).
    pub fn procedure_outputs(
        &mut self,
        p: &ProcedureOutputs,
        inputs: &CspInputs,
    ) -> (Controlword, i32) {
        let state = inputs
            .statusword
            .state()
            .unwrap_or(State::NotReadyToSwitchOn);
        let stopping = matches!(state, State::OperationEnabled | State::QuickStopActive);
        let cmd = if p.quick_stop && stopping {
            Command::QuickStop
        } else {
            next_command(state, Target::Enabled, false, self.last_cw)
        };
        self.last_cw = Controlword::of(cmd);
        self.driving = false;
        self.count_error = None;
        self.last_target = self.actual;
        let bits = if state == State::OperationEnabled {
            p.mode_bits & MODE_BITS
        } else {
            0
        };
        (Controlword(self.last_cw.0 | bits), inputs.position)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia402::objects;
    use crate::cia402::Statusword;
    use crate::csp::encode_outputs;
    use crate::scaling::ScalingConfig;

    fn channel() -> CspChannel {
        CspChannel::new(
            Scaling::new(ScalingConfig {
                counts_per_motor_rev: 10_000,
                motor_revs: 1,
                load_revs: 1,
                units_per_load_rev: 10.0,
                invert: false,
            })
            .unwrap(),
        )
    }

    #[test]
    fn inputs_round_trip_and_short_buffers_are_refused() {
        let min = CspOffsets::minimal();
        let mut out = [0u8; 6];
        encode_outputs(&min, &mut out, Controlword(0x0F), -5);
        assert_eq!(out, [0x0F, 0, 0xFB, 0xFF, 0xFF, 0xFF]);
        let i = CspInputs::decode(&min, &[0x37, 0x06, 0x10, 0x27, 0, 0]).unwrap();
        assert_eq!(i.statusword.state(), Some(State::OperationEnabled));
        assert_eq!(i.position, 10_000);
        assert_eq!(
            CspInputs::decode(&min, &[1, 2, 3]).unwrap_err().to_string(),
            "process data inputs (TxPDO): 3 bytes, the PDO layout maps 6"
        );
        assert!(channel().decode(&[1, 2, 3]).is_none());
        let fb = channel().drive_feedback(&i);
        assert_eq!(fb.position, 10.0);
        assert!(fb.operation_enabled);
    }

    #[test]
    fn holds_actual_until_enabled_then_follows_the_set_value() {
        let mut ch = channel();
        let sp = CspSetpoint {
            position: 2.0,
            enable: true,
            ..CspSetpoint::default()
        };
        let disabled = CspInputs {
            statusword: Statusword(0x0250),
            position: 777,
            ..CspInputs::default()
        };
        assert_eq!(ch.drive_outputs(&sp, &disabled), (Controlword(0x06), 777));
        let enabled = CspInputs {
            statusword: Statusword(0x0637),
            position: 777,
            ..CspInputs::default()
        };
        assert_eq!(ch.drive_outputs(&sp, &enabled), (Controlword(0x0F), 2000));
        let off = CspSetpoint {
            enable: false,
            ..sp
        };
        assert_eq!(ch.drive_outputs(&off, &enabled).0, Controlword(0x00));
    }

    #[test]
    fn a_full_layout_carries_mode_velocity_and_the_error_code() {
        let layout = PdoLayout::csp();
        let mut ch = CspChannel::with_layout(channel().scaling, &layout).unwrap();
        let mut out = [0u8; 7];
        encode_outputs(&ch.offsets, &mut out, Controlword(0x0F), 1);
        assert_eq!(out, [0x0F, 0, 1, 0, 0, 0, 8], "mode CSP in the last byte");
        // statusword Fault, position 0, velocity 1000 counts/s, torque, error 0x8700, mode.
        let mut inp = [0u8; 15];
        inp[0..2].copy_from_slice(&0x0218u16.to_le_bytes());
        inp[6..10].copy_from_slice(&1000i32.to_le_bytes());
        inp[12..14].copy_from_slice(&0x8700u16.to_le_bytes());
        let i = ch.decode(&inp).unwrap();
        let fb = ch.drive_feedback(&i);
        assert_eq!(fb.fault, Some(0x8700));
        assert!(
            (fb.velocity - 1.0).abs() < 1e-12,
            "1000 counts/s = 1 unit/s"
        );
        let no_target = PdoLayout {
            outputs: vec![objects::CONTROLWORD],
            inputs: layout.inputs.clone(),
        };
        assert_eq!(
            CspChannel::with_layout(channel().scaling, &no_target)
                .unwrap_err()
                .to_string(),
            "the PDO layout lacks 0x607a Target position, which CSP needs"
        );
    }

    const ENABLED: Statusword = Statusword(0x0637);

    fn enabled_at(position: i32) -> CspInputs {
        CspInputs {
            statusword: ENABLED,
            position,
            ..CspInputs::default()
        }
    }

    /// 10 000 counts per motor turn through 7:3: 23 333⅓ counts per 360°.
    fn geared_rotary() -> CspChannel {
        let mut ch = CspChannel::new(
            Scaling::new(ScalingConfig {
                counts_per_motor_rev: 10_000,
                motor_revs: 7,
                load_revs: 3,
                units_per_load_rev: 360.0,
                invert: false,
            })
            .unwrap(),
        );
        ch.set_modulo_period(Some(360.0)).unwrap();
        ch
    }

    fn sp(turns: i64, position: f64) -> CspSetpoint {
        CspSetpoint {
            position,
            turns,
            enable: true,
            ..CspSetpoint::default()
        }
    }

    #[test]
    fn a_modulo_axis_takes_over_where_the_drive_stands_and_counts_on_across_wraps() {
        // The drive powers up 214.3 periods into its counter; the kernel's frame has its
        // own turn count (here −4) and sees only the position within the period.
        for start in [5_000_000, -3_000_001, i32::MAX - 20_000, i32::MIN + 7] {
            let mut ch = geared_rotary();
            let fb = ch.drive_feedback(&enabled_at(start));
            assert!((0.0..360.0).contains(&fb.position), "{fb:?}");
            let (mut turns, mut within) = (-4i64, fb.position);
            let (_, target) = ch.drive_outputs(&sp(turns, within), &enabled_at(start));
            assert_eq!(target, start, "the first target is the actual position");
            // 30 periods forward at 7.3° per cycle, then 60 back: every step is the
            // cycle's travel in counts (±1 for rounding) also when the kernel wraps and
            // the drive's 32-bit counter wraps.
            let counts_per_degree = 10_000.0 * 7.0 / 3.0 / 360.0;
            let (mut last, mut actual) = (target, start);
            let mut total = 0.0;
            for (cycles, step) in [(1480, 7.3), (2960, -7.3)] {
                for _ in 0..cycles {
                    within += step;
                    total += step;
                    if within >= 360.0 {
                        within -= 360.0;
                        turns += 1;
                    } else if within < 0.0 {
                        within += 360.0;
                        turns -= 1;
                    }
                    ch.drive_feedback(&enabled_at(actual));
                    let (_, t) = ch.drive_outputs(&sp(turns, within), &enabled_at(actual));
                    let d = f64::from(t.wrapping_sub(last));
                    assert!(
                        (d - step * counts_per_degree).abs() <= 1.0,
                        "step {d} counts at turns {turns} within {within} (start {start})"
                    );
                    last = t;
                    actual = t;
                }
            }
            let travelled = i64::from(last.wrapping_sub(start));
            let expect = (total * counts_per_degree).round() as i64;
            assert!((travelled - expect).abs() <= 1, "{travelled} vs {expect}");
        }
    }

    #[test]
    fn the_drive_counter_wraps_at_2_pow_31_and_the_feedback_extends_past_it() {
        let mut ch = channel();
        // 1000 counts per unit.
        let fb = ch.drive_feedback(&enabled_at(i32::MAX - 5));
        assert_eq!(fb.position, f64::from(i32::MAX - 5) / 1000.0);
        ch.drive_outputs(&sp(0, fb.position), &enabled_at(i32::MAX - 5));
        // The drive went 11 counts on: its counter reads −2³¹ + 5; gantry's count 2³¹ + 5.
        let fb = ch.drive_feedback(&enabled_at(i32::MIN + 5));
        assert_eq!(ch.actual_counts(), (1i64 << 31) + 5);
        assert_eq!(fb.position, ((1i64 << 31) + 5) as f64 / 1000.0);
        // A target 3·2³¹ counts out is sent as its low half.
        let far = 3.0 * f64::from(1u32 << 31) / 1000.0 + 0.002;
        let (_, t) = ch.drive_outputs(&sp(0, far), &enabled_at(i32::MIN + 5));
        assert_eq!(t, ((3i64 << 31) + 2) as i32);
        assert_eq!(t, i32::MIN + 2);
        assert_eq!(ch.count_error(), None);
        // And back below −2³¹.
        let mut ch = channel();
        ch.drive_feedback(&enabled_at(i32::MIN + 1));
        ch.drive_feedback(&enabled_at(i32::MAX));
        assert_eq!(ch.actual_counts(), -(1i64 << 31) - 1);
    }

    #[test]
    fn a_set_position_with_no_64_bit_count_faults_the_axis_and_sends_nothing_new() {
        // 2^32 · 2^32 counts per 1e-6 unit: one unit is ~1.8e25 counts.
        let mut ch = CspChannel::new(
            Scaling::new(ScalingConfig {
                counts_per_motor_rev: u32::MAX,
                motor_revs: u32::MAX,
                load_revs: 1,
                units_per_load_rev: 1e-6,
                invert: false,
            })
            .unwrap(),
        );
        let fb = ch.drive_feedback(&enabled_at(100));
        assert_eq!(fb.fault, None);
        assert_eq!(
            ch.drive_outputs(&sp(0, fb.position), &enabled_at(100)).1,
            100
        );
        let (_, t) = ch.drive_outputs(&sp(0, 1.0), &enabled_at(100));
        assert_eq!(t, 100, "the drive keeps its last target");
        assert_eq!(
            ch.count_error().unwrap().to_string(),
            "set position 1 (+ 0 periods) has no 64-bit drive count"
        );
        let fb = ch.drive_feedback(&enabled_at(100));
        assert_eq!(fb.fault, Some(COUNT_RANGE_FAULT));
        assert!(crate::cia402::error_code::describe(COUNT_RANGE_FAULT)
            .contains("no 64-bit drive count"));
        // The drive's own fault comes first.
        let faulted = CspInputs {
            statusword: Statusword(0x0218),
            error_code: Some(0x8611),
            ..enabled_at(100)
        };
        assert_eq!(ch.drive_feedback(&faulted).fault, Some(0x8611));
        // Back in range, the axis is no longer faulted by the channel.
        ch.drive_outputs(&sp(0, fb.position), &enabled_at(100));
        assert_eq!(ch.count_error(), None);
        assert_eq!(ch.drive_feedback(&enabled_at(100)).fault, None);
    }

    #[test]
    fn a_period_of_less_than_a_count_makes_the_channel_unusable() {
        // 10 counts per 360°: a 1° period is 1/36 count.
        let mut ch = CspChannel::new(
            Scaling::new(ScalingConfig {
                counts_per_motor_rev: 10,
                motor_revs: 1,
                load_revs: 1,
                units_per_load_rev: 360.0,
                invert: false,
            })
            .unwrap(),
        );
        assert!(ch.set_modulo_period(Some(1.0)).is_err());
        assert!(ch.unusable().is_some());
        assert_eq!(
            ch.drive_feedback(&enabled_at(7)).fault,
            Some(COUNT_RANGE_FAULT)
        );
        assert_eq!(
            ch.drive_outputs(&sp(0, 0.5), &enabled_at(7)).1,
            7,
            "held at the actual"
        );
        ch.set_modulo_period(Some(360.0)).unwrap();
        assert_eq!(ch.drive_feedback(&enabled_at(7)).fault, None);
    }
}
