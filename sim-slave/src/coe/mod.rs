//! CANopen over EtherCAT (CoE, ETG.1000.6 §5.6): the mailbox header, the CoE header and an
//! SDO server over an [`od::ObjectDictionary`]. Expedited and normal (in one mailbox)
//! uploads and downloads; complete access and segmented transfers are refused with an
//! abort, so masters fall back to sub-index access.

pub mod od;
pub mod pdo;

use od::{ObjectDictionary, OdError};

/// Mailbox header length.
pub const MAILBOX_HEADER_LEN: usize = 6;
/// Mailbox type of CoE.
pub const MAILBOX_TYPE_COE: u8 = 3;
/// CoE service: SDO request.
pub const COE_SDO_REQUEST: u16 = 2;
/// CoE service: SDO response.
pub const COE_SDO_RESPONSE: u16 = 3;

/// SDO abort codes (CiA 301 Table 22) the server sends.
pub mod abort {
    /// Command specifier not valid or unknown.
    pub const BAD_COMMAND: u32 = 0x0504_0001;
    /// Unsupported access to an object.
    pub const UNSUPPORTED_ACCESS: u32 = 0x0601_0000;
    /// Attempt to write a read-only object.
    pub const READ_ONLY: u32 = 0x0601_0002;
    /// Object does not exist.
    pub const NO_OBJECT: u32 = 0x0602_0000;
    /// Data type does not match, length of service parameter does not match.
    pub const LENGTH: u32 = 0x0607_0010;
    /// Sub-index does not exist.
    pub const NO_SUB_INDEX: u32 = 0x0609_0011;
    /// Object cannot be mapped to the PDO.
    pub const NOT_MAPPABLE: u32 = 0x0604_0041;
    /// The number and length of the objects to be mapped would exceed the PDO length.
    pub const PDO_TOO_LONG: u32 = 0x0604_0042;
    /// Data cannot be transferred or stored because of the present device state.
    pub const DEVICE_STATE: u32 = 0x0800_0022;
}

fn abort_code(e: OdError) -> u32 {
    match e {
        OdError::NoObject => abort::NO_OBJECT,
        OdError::NoSubIndex => abort::NO_SUB_INDEX,
        OdError::ReadOnly => abort::READ_ONLY,
        OdError::LengthMismatch => abort::LENGTH,
        OdError::WrongState => abort::DEVICE_STATE,
        OdError::NotMappable => abort::NOT_MAPPABLE,
        OdError::PdoTooLong => abort::PDO_TOO_LONG,
    }
}

/// Serves one mailbox write (`request`: the whole SM0 area) and returns the response
/// mailbox (to be placed in the SM1 area), or `None` when the request is not CoE SDO
/// (the mailbox is then ignored, as for an unsupported protocol).
pub fn serve(od: &mut ObjectDictionary, request: &[u8]) -> Option<Vec<u8>> {
    let len = u16::from_le_bytes([*request.first()?, *request.get(1)?]) as usize;
    let kind = request.get(5)? & 0x0F;
    let counter = (request.get(5)? >> 4) & 0x07;
    if kind != MAILBOX_TYPE_COE {
        return None;
    }
    let body = request.get(MAILBOX_HEADER_LEN..MAILBOX_HEADER_LEN + len)?;
    let coe = u16::from_le_bytes([*body.first()?, *body.get(1)?]);
    if coe >> 12 != COE_SDO_REQUEST {
        return None;
    }
    let sdo = body.get(2..)?;
    let cmd = *sdo.first()?;
    let index = u16::from_le_bytes([*sdo.get(1)?, *sdo.get(2)?]);
    let sub = *sdo.get(3)?;
    let coe_reply = |service: u16, payload: Vec<u8>| {
        let mut out = Vec::with_capacity(MAILBOX_HEADER_LEN + 2 + payload.len());
        out.extend(((2 + payload.len()) as u16).to_le_bytes());
        out.extend([0, 0, 0, MAILBOX_TYPE_COE | (counter << 4)]);
        out.extend((service << 12).to_le_bytes());
        out.extend(payload);
        out
    };
    let reply = |payload: Vec<u8>| coe_reply(COE_SDO_RESPONSE, payload);
    // ETG.1000.6 Table 40: "Abort SDO Transfer Request" travels with the CoE service
    // "SDO request" (2), whichever side aborts; masters (SOEM) tell an abort from a
    // response by that service before they look at the command specifier.
    let aborted = |code: u32| {
        let mut p = vec![0x80];
        p.extend(index.to_le_bytes());
        p.push(sub);
        p.extend(code.to_le_bytes());
        coe_reply(COE_SDO_REQUEST, p)
    };
    if cmd & 0x10 != 0 {
        return Some(aborted(abort::UNSUPPORTED_ACCESS));
    }
    let ccs = cmd >> 5;
    let response = match ccs {
        // Upload (read).
        2 => match od.read(index, sub) {
            Ok(v) if v.len() <= 4 => {
                let n = 4 - v.len() as u8;
                let mut p = vec![0x43 | (n << 2)];
                p.extend(index.to_le_bytes());
                p.push(sub);
                let mut data = [0u8; 4];
                data.get_mut(..v.len())?.copy_from_slice(v);
                p.extend(data);
                reply(p)
            }
            Ok(v) => {
                let mut p = vec![0x41];
                p.extend(index.to_le_bytes());
                p.push(sub);
                p.extend((v.len() as u32).to_le_bytes());
                p.extend_from_slice(v);
                reply(p)
            }
            Err(e) => aborted(abort_code(e)),
        },
        // Download (write).
        1 => {
            let expedited = cmd & 0x02 != 0;
            let data: Vec<u8> = if expedited {
                let n = if cmd & 0x01 != 0 {
                    ((cmd >> 2) & 0x03) as usize
                } else {
                    0
                };
                sdo.get(4..8 - n)?.to_vec()
            } else {
                let size = u32::from_le_bytes(sdo.get(4..8)?.try_into().ok()?) as usize;
                sdo.get(8..8 + size)?.to_vec()
            };
            match od.write(index, sub, &data) {
                Ok(()) => {
                    let mut p = vec![0x60];
                    p.extend(index.to_le_bytes());
                    p.push(sub);
                    p.extend([0, 0, 0, 0]);
                    reply(p)
                }
                Err(e) => aborted(abort_code(e)),
            }
        }
        _ => aborted(abort::BAD_COMMAND),
    };
    Some(response)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(sdo: &[u8]) -> Vec<u8> {
        let mut m = vec![0u8; 128];
        let len = (2 + sdo.len()) as u16;
        m[0..2].copy_from_slice(&len.to_le_bytes());
        m[5] = MAILBOX_TYPE_COE | (3 << 4);
        m[6..8].copy_from_slice(&(COE_SDO_REQUEST << 12).to_le_bytes());
        m[8..8 + sdo.len()].copy_from_slice(sdo);
        m
    }

    fn sdo_of(resp: &[u8]) -> &[u8] {
        assert_eq!(resp[5] & 0x0F, MAILBOX_TYPE_COE);
        assert_eq!((resp[5] >> 4) & 7, 3, "counter echoed");
        let service = u16::from_le_bytes([resp[6], resp[7]]) >> 12;
        let expected = if resp[8] == 0x80 {
            COE_SDO_REQUEST
        } else {
            COE_SDO_RESPONSE
        };
        assert_eq!(service, expected);
        &resp[8..]
    }

    #[test]
    fn expedited_upload_of_one_two_and_four_bytes() {
        let mut od = ObjectDictionary::cia402_servo(0xAA, 0xBB, 1, 2);
        let r = serve(&mut od, &request(&[0x40, 0x12, 0x1C, 0x00, 0, 0, 0, 0])).unwrap();
        assert_eq!(&sdo_of(&r)[..5], &[0x4F, 0x12, 0x1C, 0x00, 1]);
        let r = serve(&mut od, &request(&[0x40, 0x12, 0x1C, 0x01, 0, 0, 0, 0])).unwrap();
        assert_eq!(&sdo_of(&r)[..6], &[0x4B, 0x12, 0x1C, 0x01, 0x00, 0x16]);
        let r = serve(&mut od, &request(&[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0])).unwrap();
        assert_eq!(&sdo_of(&r)[..8], &[0x43, 0x18, 0x10, 0x01, 0xAA, 0, 0, 0]);
    }

    #[test]
    fn downloads_and_aborts() {
        let mut od = ObjectDictionary::cia402_servo(1, 2, 3, 4);
        let r = serve(&mut od, &request(&[0x2F, 0x60, 0x60, 0x00, 9, 0, 0, 0])).unwrap();
        assert_eq!(sdo_of(&r)[0], 0x60);
        assert_eq!(od.read(0x6060, 0), Ok(&[9u8][..]));
        let abort_of = |r: &[u8]| u32::from_le_bytes(sdo_of(r)[4..8].try_into().unwrap());
        let r = serve(&mut od, &request(&[0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0])).unwrap();
        assert_eq!(sdo_of(&r)[0], 0x80);
        assert_eq!(abort_of(&r), abort::NO_OBJECT);
        let r = serve(&mut od, &request(&[0x23, 0x00, 0x10, 0x00, 1, 2, 3, 4])).unwrap();
        assert_eq!(abort_of(&r), abort::READ_ONLY);
        let r = serve(&mut od, &request(&[0x50, 0x12, 0x1C, 0x00, 0, 0, 0, 0])).unwrap();
        assert_eq!(abort_of(&r), abort::UNSUPPORTED_ACCESS, "complete access");
        let r = serve(&mut od, &request(&[0xE0, 0x12, 0x1C, 0x00, 0, 0, 0, 0])).unwrap();
        assert_eq!(abort_of(&r), abort::BAD_COMMAND);
    }

    #[test]
    fn aborts_are_sdo_requests_with_the_abort_specifier() {
        let mut od = ObjectDictionary::cia402_servo(1, 2, 3, 4);
        let r = serve(&mut od, &request(&[0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0])).unwrap();
        assert_eq!(
            u16::from_le_bytes([r[0], r[1]]),
            10,
            "CoE header + 8 SDO bytes"
        );
        assert_eq!(
            u16::from_le_bytes([r[6], r[7]]) >> 12,
            COE_SDO_REQUEST,
            "an abort is an SDO request (ETG.1000.6 Table 40), not a response"
        );
        assert_eq!(r[8], 0x80);
        assert_eq!(&r[9..12], &[0x00, 0x20, 0x00], "index and sub-index echoed");
        assert_eq!(
            u32::from_le_bytes(r[12..16].try_into().unwrap()),
            abort::NO_OBJECT
        );
    }

    #[test]
    fn non_coe_and_garbage_get_no_answer() {
        let mut od = ObjectDictionary::default();
        let mut m = request(&[0x40, 0, 0, 0, 0, 0, 0, 0]);
        m[5] = 0x04; // FoE
        assert!(serve(&mut od, &m).is_none());
        assert!(serve(&mut od, &[1, 2]).is_none());
        let mut huge = request(&[0x40, 0, 0, 0]);
        huge[0] = 0xFF;
        assert!(serve(&mut od, &huge).is_none());
    }
}
