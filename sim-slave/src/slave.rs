//! One emulated slave: its ESC memory, EEPROM and AL state, serving the datagrams that
//! pass through it, plus the side effects a real ESC has when a register is written (AL
//! control starts a state change, SII control starts an EEPROM access).

use crate::esc::al::{self, AlStatusCode};
use crate::esc::command::{self, Served};
use crate::esc::datagram::Datagram;
use crate::esc::memory::Memory;
use crate::esc::registers::{AL_CONTROL, AL_STATUS, AL_STATUS_CODE, DL_STATUS};
use crate::esc::sii::{self, DeviceDescription, Sii};
use crate::plant::DeviceModel;

/// An emulated slave.
#[derive(Clone, Debug)]
pub struct Slave {
    memory: Memory,
    sii: Sii,
    description: DeviceDescription,
    device: DeviceModel,
}

impl Slave {
    /// A slave in Init with its EEPROM generated from `description`.
    pub fn new(description: DeviceDescription) -> Self {
        let sii = Sii::new(description.image());
        let mut memory = Memory::new();
        sii.reset(&mut memory);
        Self {
            memory,
            sii,
            description,
            device: DeviceModel::None,
        }
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

    /// Runs `dt_s` seconds of the application (device models read outputs and write inputs).
    pub fn tick(&mut self, dt_s: f64) {
        self.device.step(&mut self.memory, dt_s);
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

    /// Sets DL status (0x0110) for the ports that are wired: link and communication on a
    /// wired port, loop closed on an open one; PDI operational (the EEPROM was loaded).
    pub fn set_ports(&mut self, wired: [bool; 4]) {
        let mut v: u16 = 1; // PDI operational
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
        let ado = d.ado();
        let len = d.data_len();
        let served = command::serve(&mut self.memory, d);
        let wrote =
            matches!(served, Served::Written | Served::ReadWritten) && !d.command().is_logical();
        if wrote {
            let touched = |reg: u16, w: usize| {
                (ado as usize) < reg as usize + w && (ado as usize + len) > reg as usize
            };
            if touched(AL_CONTROL, 2) {
                self.on_al_control();
            }
            if sii::touches_control(ado, len) {
                self.sii.on_control_write(&mut self.memory);
            }
        }
        served
    }

    fn on_al_control(&mut self) {
        let control = self.memory.read_u16(AL_CONTROL);
        let status = self.memory.read_u16(AL_STATUS);
        let code = AlStatusCode::from_raw(self.memory.read_u16(AL_STATUS_CODE));
        // Device checks of SyncManager/PDO configuration come with the SyncManager model.
        let out = al::on_control(status, code, control, false, |_, _| Ok(()));
        self.memory.pdi_write(AL_STATUS, &out.status.to_le_bytes());
        self.memory
            .pdi_write(AL_STATUS_CODE, &out.code.raw().to_le_bytes());
    }
}
