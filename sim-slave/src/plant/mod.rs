//! Device models behind the ESCs: what a slave's application does with its process data
//! each cycle: a CiA-402 servo drive in cyclic synchronous position mode, an incremental
//! encoder module, and a digital-input module whose inputs are switch cams along a servo's
//! travel.

pub mod encoder;
pub mod record;
pub mod servo;
pub mod switches;

use crate::esc::al::AlState;
use crate::esc::memory::Memory;

/// What a slave's AL state lets its application exchange with the master (ETG.1000.6
/// §6.4.1): inputs are valid from SafeOp on; outputs are taken only in Op (in SafeOp they
/// stay in their safe state, all zero). The application itself (a shaft turning, a counter
/// counting) runs in every state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Exchange {
    /// The application writes its inputs.
    pub inputs: bool,
    /// The application takes the master's outputs.
    pub outputs: bool,
}

impl Exchange {
    /// Operational: both ways.
    pub const OP: Self = Self {
        inputs: true,
        outputs: true,
    };

    /// What `state` allows.
    pub fn in_state(state: AlState) -> Self {
        Self {
            inputs: matches!(state, AlState::SafeOp | AlState::Op),
            outputs: state == AlState::Op,
        }
    }
}

/// The application of a slave.
// A servo's model is larger than the others'; each slave holds one, built once.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, Default)]
pub enum DeviceModel {
    /// No application (an ESC alone, e.g. a coupler).
    #[default]
    None,
    /// A CiA-402 servo drive.
    Servo(servo::ServoDrive),
    /// An incremental encoder module counting an external shaft.
    Encoder(encoder::EncoderModule),
    /// Digital inputs actuated by cams on another slave's axis.
    Switches(switches::SwitchesModule),
}

impl DeviceModel {
    /// The master mapped this process data layout (PreOp → SafeOp).
    pub fn configure_pdo(&mut self, layout: gantry_drives::cia402::pdo::PdoLayout) {
        match self {
            DeviceModel::Servo(s) => s.configure(layout),
            // Fixed PDOs from the EEPROM: nothing to configure.
            DeviceModel::None | DeviceModel::Encoder(_) | DeviceModel::Switches(_) => {}
        }
    }

    /// Before the slave serves an SDO request: the device writes its present values
    /// into its dictionary, so that an upload reads them.
    pub fn publish_objects(&self, od: &mut crate::coe::od::ObjectDictionary) {
        if let DeviceModel::Servo(s) = self {
            s.publish_objects(od);
        }
    }

    /// After the slave served an SDO request: the device takes what was written.
    pub fn take_objects(&mut self, od: &crate::coe::od::ObjectDictionary) {
        if let DeviceModel::Servo(s) = self {
            s.take_objects(od);
        }
    }

    /// The process-data watchdog expired: the master is gone.
    pub fn on_watchdog(&mut self) {
        match self {
            DeviceModel::Servo(s) => s.on_watchdog(),
            // The encoder keeps counting (its outputs only set the counter); inputs have
            // no outputs to watch.
            DeviceModel::None | DeviceModel::Encoder(_) | DeviceModel::Switches(_) => {}
        }
    }

    /// Runs `dt_s` seconds of the application against the slave's memory: takes the
    /// outputs, runs, publishes the inputs, as far as `exchange` allows.
    pub fn step(&mut self, mem: &mut Memory, dt_s: f64, exchange: Exchange) {
        match self {
            DeviceModel::None => {}
            DeviceModel::Servo(s) => {
                if exchange.outputs {
                    s.take_outputs(mem);
                }
                s.run(dt_s);
                if exchange.inputs {
                    s.publish_inputs(mem);
                }
            }
            DeviceModel::Encoder(e) => e.step(mem, dt_s, exchange),
            DeviceModel::Switches(s) => s.step(mem, exchange),
        }
    }

    /// Takes the outputs the master wrote, as a drive does at its SYNC0 edge (DC) or when
    /// the frame has written them (free run). Only a servo samples them apart from its
    /// run; the other modules read their outputs as they run.
    pub fn take_outputs(&mut self, mem: &Memory) {
        match self {
            DeviceModel::Servo(s) => s.take_outputs(mem),
            DeviceModel::None | DeviceModel::Encoder(_) | DeviceModel::Switches(_) => {}
        }
    }

    /// The position this device reports as its axis' actual position (counts), for
    /// devices coupled to it: a servo's position actual value.
    pub fn axis_position(&self) -> Option<i64> {
        match self {
            DeviceModel::Servo(s) => Some(s.position_counts()),
            DeviceModel::None | DeviceModel::Encoder(_) | DeviceModel::Switches(_) => None,
        }
    }

    /// What a drive recorded of the setpoints it took; `None` for devices without a drive.
    pub fn record(&self) -> Option<&record::DriveRecord> {
        match self {
            DeviceModel::Servo(s) => Some(s.record()),
            DeviceModel::None | DeviceModel::Encoder(_) | DeviceModel::Switches(_) => None,
        }
    }

    /// A drive's record, mutable (the ESC side counts missed and doubled setpoints).
    pub fn record_mut(&mut self) -> Option<&mut record::DriveRecord> {
        match self {
            DeviceModel::Servo(s) => Some(s.record_mut()),
            DeviceModel::None | DeviceModel::Encoder(_) | DeviceModel::Switches(_) => None,
        }
    }

    /// The chain index of the slave whose axis this device watches, if it watches one.
    pub fn coupled_axis(&self) -> Option<usize> {
        match self {
            DeviceModel::Switches(s) => Some(s.axis),
            DeviceModel::None | DeviceModel::Servo(_) | DeviceModel::Encoder(_) => None,
        }
    }

    /// The watched axis is at `position` (counts).
    pub fn on_axis_position(&mut self, mem: &mut Memory, position: i64, exchange: Exchange) {
        if let DeviceModel::Switches(s) = self {
            s.sense(mem, position, exchange);
        }
    }
}
