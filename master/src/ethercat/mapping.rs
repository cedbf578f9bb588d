//! Mapping a drive's PDOs from the configuration: the layout's SDO downloads, in PreOp,
//! before the group goes to SafeOp (where ethercrab sizes the process image by reading
//! the same objects back). Not vendor-specific: any CoE drive with configurable mapping.

use std::ops::Deref;

use ethercrab::{SubDevice, SubDeviceRef};
use gantry_drives::cia402::pdo::{PdoLayout, SdoWrite};
use thiserror::Error;

/// A download the drive refused.
#[derive(Debug, Error)]
#[error("slave {address:#06x}: SDO download {index:#06x}:{sub:02} = {value} refused: {source}")]
pub struct MappingError {
    /// Station address.
    pub address: u16,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The value, in hex.
    pub value: String,
    /// ethercrab's error (for an abort: the abort code and its text).
    pub source: ethercrab::error::Error,
}

/// Writes `layout` into the drive behind `sd` (which must be in PreOp).
pub async fn map_pdos<S>(sd: &SubDeviceRef<'_, S>, layout: &PdoLayout) -> Result<(), MappingError>
where
    S: Deref<Target = SubDevice>,
{
    download(sd, layout.sdo_writes()).await
}

/// Downloads `writes` in order (values of 1, 2 or 4 bytes); the first refusal ends it.
pub async fn download<S>(
    sd: &SubDeviceRef<'_, S>,
    writes: Vec<SdoWrite>,
) -> Result<(), MappingError>
where
    S: Deref<Target = SubDevice>,
{
    for SdoWrite { index, sub, value } in writes {
        let result = match value.as_slice() {
            [a] => sd.sdo_write(index, sub, *a).await,
            [a, b] => sd.sdo_write(index, sub, u16::from_le_bytes([*a, *b])).await,
            [a, b, c, d] => {
                sd.sdo_write(index, sub, u32::from_le_bytes([*a, *b, *c, *d]))
                    .await
            }
            _ => Ok(()),
        };
        result.map_err(|source| MappingError {
            address: sd.configured_address(),
            index,
            sub,
            value: value
                .iter()
                .rev()
                .map(|b| format!("{b:02x}"))
                .collect::<String>(),
            source,
        })?;
    }
    Ok(())
}
