//! Switch cams along an axis, read by a digital-input terminal (in the manner of a Beckhoff
//! EL1008: 8 inputs, one byte). Each input is wired to one switch — a reference switch, a
//! positive or negative limit switch — that a cam on the moving axis actuates over a
//! range of positions.
//!
//! The module watches one axis: a servo elsewhere in the chain, named by its index.
//! [`crate::chain::SlaveChain::tick`] passes that servo's actual position (the value the
//! servo reports, in counts) to the module after every application step, so the switch
//! inputs and the position the master reads in the same frame agree to the count.
//!
//! Process data (fixed PDOs in the EEPROM, no CoE): inputs (TxPDO 0x1A00…0x1A07, one per
//! channel) `0x6000 + 0x10·n :01 input n: 1 bit`, eight bits in one byte.

use thiserror::Error;

use super::Exchange;
use crate::esc::memory::Memory;

/// Number of inputs.
pub const INPUTS: u8 = 8;
/// Bytes of the input process data.
pub const INPUT_BYTES: usize = 1;
/// Object of input channel 0 (channel n at 0x6000 + 0x10·n, sub-index 1).
pub const DI_CHANNEL_0: u16 = 0x6000;
/// First TxPDO (one per channel).
pub const TXPDO_CHANNEL_0: u16 = 0x1A00;

/// A cam on the axis that actuates the switch on one input while the axis is in
/// `from..=to` (counts, both ends included).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SwitchCam {
    /// Input bit (0…7).
    pub input: u8,
    /// First position (counts) at which the switch is actuated.
    pub from: i64,
    /// Last position (counts) at which the switch is actuated.
    pub to: i64,
    /// A normally closed contact: the input is high while the switch is *not* actuated,
    /// so a broken wire reads as actuated (limit switches are wired this way).
    pub normally_closed: bool,
}

impl SwitchCam {
    /// Whether the cam actuates the switch at `position`.
    pub fn actuated(&self, position: i64) -> bool {
        (self.from..=self.to).contains(&position)
    }

    /// The input level at `position`.
    pub fn level(&self, position: i64) -> bool {
        self.actuated(position) != self.normally_closed
    }
}

/// A set of cams that cannot be wired.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum CamError {
    /// The input does not exist.
    #[error("cam {cam}: input {input} does not exist (0 to 7)")]
    NoSuchInput {
        /// Index of the cam.
        cam: usize,
        /// Its input.
        input: u8,
    },
    /// The range is empty.
    #[error("cam {cam}: from {from} is above to {to}")]
    EmptyRange {
        /// Index of the cam.
        cam: usize,
        /// Its start.
        from: i64,
        /// Its end.
        to: i64,
    },
    /// Two cams on one input.
    #[error("cam {cam}: input {input} already has cam {first}")]
    InputTaken {
        /// Index of the cam.
        cam: usize,
        /// The input.
        input: u8,
        /// The cam that has it.
        first: usize,
    },
}

/// Checks that every cam has its own existing input and a non-empty range.
pub fn check_cams(cams: &[SwitchCam]) -> Result<(), CamError> {
    for (cam, c) in cams.iter().enumerate() {
        if c.input >= INPUTS {
            return Err(CamError::NoSuchInput {
                cam,
                input: c.input,
            });
        }
        if c.from > c.to {
            return Err(CamError::EmptyRange {
                cam,
                from: c.from,
                to: c.to,
            });
        }
        if let Some(first) = cams.iter().take(cam).position(|o| o.input == c.input) {
            return Err(CamError::InputTaken {
                cam,
                input: c.input,
                first,
            });
        }
    }
    Ok(())
}

/// The digital-input module and its cams.
#[derive(Clone, Debug)]
pub struct SwitchesModule {
    /// Where the input byte lies in the ESC's RAM.
    pub inputs_at: u16,
    /// Index in the chain of the servo whose position moves the cams.
    pub axis: usize,
    cams: Vec<SwitchCam>,
    /// The axis' position as last passed by the chain; `None` before the first.
    position: Option<i64>,
}

impl SwitchesModule {
    /// A module with these cams on the servo at chain index `axis`.
    pub fn new(inputs_at: u16, axis: usize, cams: Vec<SwitchCam>) -> Result<Self, CamError> {
        check_cams(&cams)?;
        Ok(Self {
            inputs_at,
            axis,
            cams,
            position: None,
        })
    }

    /// The cams.
    pub fn cams(&self) -> &[SwitchCam] {
        &self.cams
    }

    /// The input byte at the last position (before any position, no cam is actuated).
    pub fn inputs(&self) -> u8 {
        self.cams.iter().fold(0u8, |byte, c| {
            let on = match self.position {
                Some(p) => c.level(p),
                None => c.normally_closed,
            };
            byte | (u8::from(on) << (c.input % INPUTS))
        })
    }

    /// The axis is at `position` (counts): set the inputs accordingly.
    pub fn sense(&mut self, mem: &mut Memory, position: i64, exchange: Exchange) {
        self.position = Some(position);
        self.step(mem, exchange);
    }

    /// Writes the inputs for the last position (from SafeOp on: before, the master
    /// reads what the process RAM held, not the switches).
    pub fn step(&mut self, mem: &mut Memory, exchange: Exchange) {
        if exchange.inputs {
            mem.pdi_write(self.inputs_at, &[self.inputs()]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::esc::registers::PROCESS_RAM;

    const REFERENCE: SwitchCam = SwitchCam {
        input: 0,
        from: 1000,
        to: 1999,
        normally_closed: false,
    };
    const POSITIVE_LIMIT: SwitchCam = SwitchCam {
        input: 1,
        from: 5000,
        to: i64::MAX,
        normally_closed: true,
    };

    fn read(mem: &Memory) -> u8 {
        let mut b = [0u8];
        mem.ecat_read(PROCESS_RAM, &mut b, false);
        b[0]
    }

    #[test]
    fn inputs_are_published_from_safeop_on() {
        use crate::esc::al::AlState;
        let mut m = SwitchesModule::new(PROCESS_RAM, 0, vec![REFERENCE]).unwrap();
        let mut mem = Memory::new();
        m.sense(&mut mem, 1500, Exchange::in_state(AlState::PreOp));
        assert_eq!(read(&mem), 0, "PreOp: not published");
        m.sense(&mut mem, 1500, Exchange::in_state(AlState::SafeOp));
        assert_eq!(read(&mem), 0b1, "SafeOp: the reference cam");
    }

    #[test]
    fn cam_edges_are_exact_to_the_count() {
        let mut mem = Memory::new();
        let mut m = SwitchesModule::new(PROCESS_RAM, 0, vec![REFERENCE]).unwrap();
        for (p, on) in [(999, 0), (1000, 1), (1999, 1), (2000, 0), (-5, 0)] {
            m.sense(&mut mem, p, Exchange::OP);
            assert_eq!(read(&mem), on, "at {p}");
        }
    }

    #[test]
    fn normally_closed_inverts() {
        let mut mem = Memory::new();
        let mut m = SwitchesModule::new(PROCESS_RAM, 0, vec![REFERENCE, POSITIVE_LIMIT]).unwrap();
        // Before any position the switches rest: the NC contact reads high.
        m.step(&mut mem, Exchange::OP);
        assert_eq!(read(&mem), 0b10);
        m.sense(&mut mem, 4999, Exchange::OP);
        assert_eq!(read(&mem), 0b10);
        m.sense(&mut mem, 5000, Exchange::OP);
        assert_eq!(read(&mem), 0b00, "limit reached: the NC input drops");
        m.sense(&mut mem, 1500, Exchange::OP);
        assert_eq!(read(&mem), 0b11);
    }

    #[test]
    fn a_cam_outside_the_travel_never_fires() {
        let mut mem = Memory::new();
        let far = SwitchCam {
            input: 7,
            from: 1_000_000,
            to: 1_000_100,
            normally_closed: false,
        };
        let mut m = SwitchesModule::new(PROCESS_RAM, 0, vec![far]).unwrap();
        for p in (-200_000..=999_999).step_by(997).chain([999_999]) {
            m.sense(&mut mem, p, Exchange::OP);
            assert_eq!(read(&mem), 0, "at {p}");
        }
    }

    #[test]
    fn miswired_cams_are_refused() {
        let cam = |input, from, to| SwitchCam {
            input,
            from,
            to,
            normally_closed: false,
        };
        assert_eq!(
            check_cams(&[cam(8, 0, 1)]),
            Err(CamError::NoSuchInput { cam: 0, input: 8 })
        );
        assert_eq!(
            check_cams(&[cam(0, 0, 1), cam(1, 5, 4)]),
            Err(CamError::EmptyRange {
                cam: 1,
                from: 5,
                to: 4
            })
        );
        assert_eq!(
            check_cams(&[cam(0, 0, 1), cam(1, 0, 1), cam(0, 7, 9)]),
            Err(CamError::InputTaken {
                cam: 2,
                input: 0,
                first: 0
            })
        );
        assert!(check_cams(&[cam(3, 4, 4)]).is_ok(), "a one-count cam");
    }
}
