//! A kernel axis on a CSP drive channel: the kernel's set values and feedback in the drive
//! layer's terms. `gantry-kernel` and `gantry-drives` do not know each other (the kernel
//! counts nothing, the drive layer knows no axis); the master joins them here, copying
//! plain fields (no allocation: this runs in the cycle).

use gantry_drives::cia402::Controlword;
use gantry_drives::csp::probe::ProbeTarget;
use gantry_drives::csp::{CspChannel, CspFeedback, CspInputs, CspSetpoint};
use gantry_drives::scaling::ScalingError;
use gantry_kernel::axis::{AxisFeedback, AxisSetpoint};
use gantry_kernel::homing::{Latch, LimitSide, ProbeLatches, SwitchInputs};
use gantry_kernel::mechanics::Modulo;

/// A drive channel driven by a kernel axis.
pub trait AxisChannel {
    /// Counts the axis' modulo period (`None`: a normal axis); see
    /// [`CspChannel::set_modulo_period`] for the errors and what a failed call leaves.
    fn set_modulo(&mut self, modulo: Option<Modulo>) -> Result<(), ScalingError>;

    /// The axis' feedback from the drive's inputs.
    fn feedback(&mut self, inputs: &CspInputs) -> AxisFeedback;

    /// The drive's outputs for the axis' set values: controlword and 32-bit target.
    fn outputs(&mut self, sp: &AxisSetpoint, inputs: &CspInputs) -> (Controlword, i32);
}

/// The drive layer's set values of an axis' (velocity and acceleration are not sent in
/// CSP without feed-forward objects mapped).
pub fn csp_setpoint(sp: &AxisSetpoint) -> CspSetpoint {
    CspSetpoint {
        position: sp.position,
        turns: sp.turns,
        enable: sp.enable,
        reset_fault: sp.reset_fault,
        probe: match sp.probe_on_limit {
            None => ProbeTarget::Reference,
            Some(LimitSide::Negative) => ProbeTarget::NegativeLimit,
            Some(LimitSide::Positive) => ProbeTarget::PositiveLimit,
        },
    }
}

/// The kernel's feedback from the drive layer's: positions, state, the switches the drive
/// reads and the positions its touch probes latched this cycle.
pub fn axis_feedback(fb: CspFeedback) -> AxisFeedback {
    let latch = |p: Option<f64>| p.map(Latch::at).unwrap_or_default();
    AxisFeedback {
        position: fb.position,
        velocity: fb.velocity,
        operation_enabled: fb.operation_enabled,
        fault: fb.fault,
        switches: SwitchInputs {
            negative_limit: fb.switches.negative_limit,
            positive_limit: fb.switches.positive_limit,
            reference: fb.switches.home,
        },
        probe: ProbeLatches {
            rising: latch(fb.latches.rising),
            falling: latch(fb.latches.falling),
            index: latch(fb.latches.index),
        },
    }
}

impl AxisChannel for CspChannel {
    fn set_modulo(&mut self, modulo: Option<Modulo>) -> Result<(), ScalingError> {
        self.set_modulo_period(modulo.map(|m| m.period()))
    }

    fn feedback(&mut self, inputs: &CspInputs) -> AxisFeedback {
        axis_feedback(self.drive_feedback(inputs))
    }

    fn outputs(&mut self, sp: &AxisSetpoint, inputs: &CspInputs) -> (Controlword, i32) {
        self.drive_outputs(&csp_setpoint(sp), inputs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_drives::cia402::Statusword;
    use gantry_drives::csp::COUNT_RANGE_FAULT;
    use gantry_drives::scaling::{Scaling, ScalingConfig};

    /// 10 000 counts per 360°, modulo 360°.
    fn rotary() -> CspChannel {
        let mut ch = CspChannel::new(
            Scaling::new(ScalingConfig {
                counts_per_motor_rev: 10_000,
                motor_revs: 1,
                load_revs: 1,
                units_per_load_rev: 360.0,
                invert: false,
            })
            .unwrap(),
        );
        AxisChannel::set_modulo(&mut ch, Modulo::new(360.0)).unwrap();
        ch
    }

    #[test]
    fn the_axis_sees_the_drive_and_the_drive_takes_the_axis_set_values() {
        let mut ch = rotary();
        assert_eq!(ch.modulo_period(), Some(360.0));
        // Operation enabled 2.5 periods in, 1000 counts/s, error code mapped as 0.
        let inputs = CspInputs {
            statusword: Statusword(0x0637),
            position: 25_000,
            velocity: Some(1000),
            error_code: Some(0),
            ..CspInputs::default()
        };
        let fb = ch.feedback(&inputs);
        assert_eq!(
            fb,
            AxisFeedback {
                position: 180.0,
                velocity: 36.0,
                operation_enabled: true,
                fault: None,
                ..Default::default()
            }
        );
        // The axis' frame counts its own periods (here 7): taken over where the drive
        // stands, then one period on in the axis' frame is 10 000 counts on.
        let mut sp = AxisSetpoint {
            position: 180.0,
            turns: 7,
            enable: true,
            velocity: 5.0,
            ..AxisSetpoint::default()
        };
        assert_eq!(ch.outputs(&sp, &inputs), (Controlword(0x0F), 25_000));
        sp.turns = 8;
        assert_eq!(ch.outputs(&sp, &inputs).1, 35_000);
        // A reset asked by the axis reaches the drive in Fault as the fault reset edge.
        let faulted = CspInputs {
            statusword: Statusword(0x0218),
            error_code: Some(0x8611),
            ..inputs
        };
        assert_eq!(ch.feedback(&faulted).fault, Some(0x8611));
        sp.reset_fault = true;
        assert_eq!(ch.outputs(&sp, &faulted).0, Controlword(0x80));
    }

    #[test]
    fn a_period_the_drive_cannot_count_is_refused_and_faults_the_axis() {
        let mut ch = rotary();
        // 1e-9° is far less than a count.
        let e = AxisChannel::set_modulo(&mut ch, Modulo::new(1e-9)).unwrap_err();
        assert!(
            matches!(e, ScalingError::CountsPerPeriodOutOfRange { .. }),
            "{e:?}"
        );
        let inputs = CspInputs {
            statusword: Statusword(0x0637),
            ..CspInputs::default()
        };
        assert_eq!(ch.feedback(&inputs).fault, Some(COUNT_RANGE_FAULT));
        AxisChannel::set_modulo(&mut ch, None).unwrap();
        assert_eq!(ch.modulo_period(), None);
        assert_eq!(ch.feedback(&inputs).fault, None);
    }
}
