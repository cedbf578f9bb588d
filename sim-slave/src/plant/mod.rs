//! Device models behind the ESCs: what a slave's application does with its process data
//! each cycle. So far: a CiA-402 servo drive in cyclic synchronous position mode.

pub mod servo;

use crate::esc::memory::Memory;

/// The application of a slave.
#[derive(Clone, Debug, Default)]
pub enum DeviceModel {
    /// No application (an ESC alone, e.g. a coupler).
    #[default]
    None,
    /// A CiA-402 servo drive.
    Servo(servo::ServoDrive),
}

impl DeviceModel {
    /// The master mapped this process data layout (PreOp → SafeOp).
    pub fn configure_pdo(&mut self, layout: gantry_drives::cia402::pdo::PdoLayout) {
        match self {
            DeviceModel::None => {}
            DeviceModel::Servo(s) => s.configure(layout),
        }
    }

    /// The process-data watchdog expired: the master is gone.
    pub fn on_watchdog(&mut self) {
        match self {
            DeviceModel::None => {}
            DeviceModel::Servo(s) => s.on_watchdog(),
        }
    }

    /// Runs `dt_s` seconds of the application against the slave's memory.
    pub fn step(&mut self, mem: &mut Memory, dt_s: f64) {
        match self {
            DeviceModel::None => {}
            DeviceModel::Servo(s) => s.step(mem, dt_s),
        }
    }
}
