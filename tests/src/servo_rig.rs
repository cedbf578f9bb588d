//! One axis (axis 0) on one simulated servo, on either bus' lockstep rig: what the homing
//! scenarios ([`crate::homing`], [`crate::homing_matrix`], [`crate::drive_homing`]) need of
//! a rig, written once per bus.

use gantry::runtime::bus::CycleBus;
use gantry::runtime::controller::{CommandHandle, Controller};
use gantry_kernel::axis::handle::CommandStatus;
use gantry_kernel::axis::status::AxisStatus;
use gantry_sim::plant::servo::ServoDrive;

use crate::can_rig::CanRig;
use crate::rig::Rig;

/// A lockstep rig with axis 0 on a simulated servo.
pub trait ServoRig {
    /// The application's controller.
    fn ctl(&self) -> &Controller;
    /// Cycles until `h` is final (at most `max` cycles).
    fn finish(&mut self, h: &CommandHandle, max: usize) -> CommandStatus;
    /// `n` cycles.
    fn cycles(&mut self, n: usize);
    /// The axis' status now.
    fn status(&self) -> AxisStatus;
    /// The status of command `id`, while the engine remembers it.
    fn command_status(&self, id: u64) -> Option<CommandStatus>;
    /// `f` of the simulated servo.
    fn with_servo<R>(&self, f: impl FnOnce(&ServoDrive) -> R) -> R;
    /// The cycle time (s).
    fn cycle_s(&self) -> f64;
    /// Frames (EtherCAT) or TPDO sets (CANopen) lost so far.
    fn lost_frames(&self) -> u64;
}

/// The EtherCAT rig with its servo at bus position 0.
pub struct EthercatServo {
    /// The rig.
    pub rig: Rig,
    /// Its cycle time (s).
    pub cycle_s: f64,
}

impl ServoRig for EthercatServo {
    fn ctl(&self) -> &Controller {
        &self.rig.ctl
    }
    fn finish(&mut self, h: &CommandHandle, max: usize) -> CommandStatus {
        self.rig.finish(h, max)
    }
    fn cycles(&mut self, n: usize) {
        self.rig.run(n);
    }
    fn status(&self) -> AxisStatus {
        *self.rig.engine.cycle.kernel.axis_status(0).expect("axis 0")
    }
    fn command_status(&self, id: u64) -> Option<CommandStatus> {
        self.rig.engine.command_status(id)
    }
    fn with_servo<R>(&self, f: impl FnOnce(&ServoDrive) -> R) -> R {
        self.rig.servo(0, f)
    }
    fn cycle_s(&self) -> f64 {
        self.cycle_s
    }
    fn lost_frames(&self) -> u64 {
        self.rig.engine.bus.counters().lost
    }
}

/// The CANopen rig with its servo at node `node`.
pub struct CanopenServo {
    /// The rig.
    pub rig: CanRig,
    /// The servo's node id.
    pub node: u8,
    /// Its cycle time (s).
    pub cycle_s: f64,
}

impl ServoRig for CanopenServo {
    fn ctl(&self) -> &Controller {
        &self.rig.ctl
    }
    fn finish(&mut self, h: &CommandHandle, max: usize) -> CommandStatus {
        self.rig.finish(h, max)
    }
    fn cycles(&mut self, n: usize) {
        self.rig.run(n);
    }
    fn status(&self) -> AxisStatus {
        *self.rig.engine.cycle.kernel.axis_status(0).expect("axis 0")
    }
    fn command_status(&self, id: u64) -> Option<CommandStatus> {
        self.rig.engine.command_status(id)
    }
    fn with_servo<R>(&self, f: impl FnOnce(&ServoDrive) -> R) -> R {
        f(self.rig.sim().node(self.node).servo().expect("a servo"))
    }
    fn cycle_s(&self) -> f64 {
        self.cycle_s
    }
    fn lost_frames(&self) -> u64 {
        self.rig.engine.bus.counters().lost
    }
}
