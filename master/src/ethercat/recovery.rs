//! Bringing a slave back to OP after it left (its watchdog expired while the cable was
//! out, or it refused a state): acknowledge the latched error and request OP, as a
//! commissioning engineer does with "reset" in TwinCAT. Called from the axis reset; the
//! cyclic exchange must keep running meanwhile (the slave's watchdog wants process data).

use std::ops::Deref;

use ethercrab::{AlStatusCode, SubDevice, SubDeviceRef};
use thiserror::Error;

/// AL control register (ETG.1000.4 §6.4.1).
pub const AL_CONTROL: u16 = 0x0120;
/// AL status register.
pub const AL_STATUS: u16 = 0x0130;
/// AL state OP in the AL control/status registers.
pub const AL_STATE_OP: u16 = 0x08;
/// AL control: acknowledge the error indicated in AL status.
pub const AL_ERROR_ACK: u16 = 0x10;

/// Why a slave did not come back.
#[derive(Debug, Error)]
pub enum RecoveryError {
    /// The slave does not answer (still unplugged).
    #[error("slave {address:#06x} does not answer: {source}")]
    NoAnswer {
        /// Station address.
        address: u16,
        /// ethercrab's error.
        source: ethercrab::error::Error,
    },
    /// The slave did not finish within the time the cycle can give it.
    #[error("slave {address:#06x} did not answer within the cycle: reset again")]
    TooSlow {
        /// Station address.
        address: u16,
    },
    /// The slave refused OP.
    #[error("slave {address:#06x} refused OP: AL status {status:#06x}, {code}")]
    Refused {
        /// Station address.
        address: u16,
        /// AL status register.
        status: u16,
        /// AL status code, with its text.
        code: AlStatusCode,
    },
}

/// What recovery did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Recovered {
    /// The slave was in OP already.
    WasInOp,
    /// Its error was acknowledged and it is back in OP.
    BackInOp,
}

/// Acknowledges `sd`'s error and requests OP; checks the state it reached.
pub async fn recover_slave<S>(sd: &SubDeviceRef<'_, S>) -> Result<Recovered, RecoveryError>
where
    S: Deref<Target = SubDevice>,
{
    let address = sd.configured_address();
    let no_answer = |source| RecoveryError::NoAnswer { address, source };
    let status: u16 = sd.register_read(AL_STATUS).await.map_err(no_answer)?;
    if status == AL_STATE_OP {
        return Ok(Recovered::WasInOp);
    }
    sd.register_write(AL_CONTROL, AL_STATE_OP | AL_ERROR_ACK)
        .await
        .map_err(no_answer)?;
    let status: u16 = sd.register_read(AL_STATUS).await.map_err(no_answer)?;
    if status == AL_STATE_OP {
        return Ok(Recovered::BackInOp);
    }
    let code: AlStatusCode = sd.register_read(0x0134u16).await.map_err(no_answer)?;
    Err(RecoveryError::Refused {
        address,
        status,
        code,
    })
}
