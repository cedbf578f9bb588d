//! CANopen over EtherCAT (CoE, ETG.1000.6 §5.6): the mailbox header, the CoE header and an
//! SDO server over an [`od::ObjectDictionary`]. Expedited, normal and segmented uploads
//! and downloads (objects larger than the mailbox go in segments with the toggle bit);
//! complete access is refused with an abort, so masters fall back to sub-index access.

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
    /// Toggle bit not alternated.
    pub const TOGGLE: u32 = 0x0503_0000;
    /// Out of memory.
    pub const OUT_OF_MEMORY: u32 = 0x0504_0005;
    /// Object cannot be mapped to the PDO.
    pub const NOT_MAPPABLE: u32 = 0x0604_0041;
    /// The number and length of the objects to be mapped would exceed the PDO length.
    pub const PDO_TOO_LONG: u32 = 0x0604_0042;
    /// Data cannot be transferred or stored because of the present device state.
    pub const DEVICE_STATE: u32 = 0x0800_0022;
    /// Value range of parameter exceeded (download only).
    pub const VALUE_RANGE: u32 = 0x0609_0030;
    /// Value of parameter written too high (download only).
    pub const VALUE_TOO_HIGH: u32 = 0x0609_0031;
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
        OdError::ValueRange => abort::VALUE_RANGE,
        OdError::ValueTooHigh => abort::VALUE_TOO_HIGH,
    }
}

/// Largest object a segmented transfer carries (bounds what a master can make us hold).
pub const MAX_TRANSFER: usize = 64 * 1024;

/// A segmented transfer in progress (CiA 301 §7.2.4.3.4–5, ETG.1000.6 §5.6.2.3–6).
#[derive(Clone, Debug, PartialEq, Eq)]
enum Transfer {
    Upload {
        data: Vec<u8>,
        sent: usize,
        toggle: bool,
    },
    Download {
        index: u16,
        sub: u8,
        size: usize,
        data: Vec<u8>,
        toggle: bool,
    },
}

/// The SDO server's state between mailbox messages: a segmented transfer, if one runs.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SdoServer {
    transfer: Option<Transfer>,
}

/// Serves one mailbox write (`request`: the whole SM0 area) and returns the response
/// mailbox (at most `mailbox_len` bytes, the size of SM1), or `None` when the request is
/// not CoE SDO (the mailbox is then ignored, as for an unsupported protocol) or needs no
/// answer (an abort from the master).
pub fn serve(
    od: &mut ObjectDictionary,
    server: &mut SdoServer,
    request: &[u8],
    mailbox_len: usize,
) -> Option<Vec<u8>> {
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
    let ccs = cmd >> 5;
    // Segment messages carry no index; answers and aborts name the transfer's object.
    let (index, sub) = match (ccs, &server.transfer) {
        (0, Some(Transfer::Download { index, sub, .. })) => (*index, *sub),
        (0 | 3, _) => (0, 0),
        _ => (
            u16::from_le_bytes([*sdo.get(1)?, *sdo.get(2)?]),
            *sdo.get(3)?,
        ),
    };
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
    if ccs == 4 {
        // The master aborts: forget the transfer, answer nothing.
        server.transfer = None;
        return None;
    }
    if cmd & 0x10 != 0 && matches!(ccs, 1 | 2) {
        return Some(aborted(abort::UNSUPPORTED_ACCESS));
    }
    let response = match ccs {
        // Upload (read).
        2 => {
            server.transfer = None;
            match od.read(index, sub) {
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
                    // As much as the mailbox holds; the rest in segments.
                    let room = mailbox_len.saturating_sub(MAILBOX_HEADER_LEN + 2 + 8);
                    let first = v.len().min(room);
                    let mut p = vec![0x41];
                    p.extend(index.to_le_bytes());
                    p.push(sub);
                    p.extend((v.len() as u32).to_le_bytes());
                    p.extend_from_slice(v.get(..first)?);
                    if first < v.len() {
                        server.transfer = Some(Transfer::Upload {
                            data: v.to_vec(),
                            sent: first,
                            toggle: false,
                        });
                    }
                    reply(p)
                }
                Err(e) => aborted(abort_code(e)),
            }
        }
        // Upload segment.
        3 => {
            let toggle = cmd & 0x10 != 0;
            match server.transfer.take() {
                Some(Transfer::Upload {
                    data,
                    sent,
                    toggle: expected,
                }) if toggle == expected => {
                    let room = mailbox_len.saturating_sub(MAILBOX_HEADER_LEN + 2 + 1);
                    let chunk = (data.len() - sent).min(room.max(1));
                    let last = sent + chunk == data.len();
                    // Segments shorter than 7 bytes are padded to 7 and say how many are unused.
                    let unused = 7usize.saturating_sub(chunk) as u8;
                    let mut p = vec![(u8::from(toggle) << 4) | (unused << 1) | u8::from(last)];
                    p.extend_from_slice(data.get(sent..sent + chunk)?);
                    p.resize(1 + chunk.max(7), 0);
                    if !last {
                        server.transfer = Some(Transfer::Upload {
                            data,
                            sent: sent + chunk,
                            toggle: !toggle,
                        });
                    }
                    reply(p)
                }
                Some(Transfer::Upload { .. }) => aborted(abort::TOGGLE),
                _ => aborted(abort::BAD_COMMAND),
            }
        }
        // Download (write).
        1 => {
            server.transfer = None;
            let expedited = cmd & 0x02 != 0;
            if expedited {
                let n = if cmd & 0x01 != 0 {
                    ((cmd >> 2) & 0x03) as usize
                } else {
                    0
                };
                let data = sdo.get(4..8 - n)?.to_vec();
                write_and_answer(od, index, sub, &data, &reply, &aborted)
            } else {
                let size = u32::from_le_bytes(sdo.get(4..8)?.try_into().ok()?) as usize;
                let present = sdo.get(8..).unwrap_or(&[]);
                if size <= present.len() {
                    let data = present.get(..size)?.to_vec();
                    write_and_answer(od, index, sub, &data, &reply, &aborted)
                } else if size > MAX_TRANSFER {
                    aborted(abort::OUT_OF_MEMORY)
                } else if let Err(e) = od.read(index, sub) {
                    aborted(abort_code(e))
                } else {
                    // Segments follow.
                    server.transfer = Some(Transfer::Download {
                        index,
                        sub,
                        size,
                        data: present.to_vec(),
                        toggle: false,
                    });
                    let mut p = vec![0x60];
                    p.extend(index.to_le_bytes());
                    p.push(sub);
                    p.extend([0, 0, 0, 0]);
                    reply(p)
                }
            }
        }
        // Download segment.
        0 => {
            let toggle = cmd & 0x10 != 0;
            let last = cmd & 0x01 != 0;
            match server.transfer.take() {
                Some(Transfer::Download {
                    index,
                    sub,
                    size,
                    mut data,
                    toggle: expected,
                }) if toggle == expected => {
                    let seg = sdo.get(1..).unwrap_or(&[]);
                    // A 7-byte segment says how many of its bytes are unused.
                    let used = if seg.len() == 7 {
                        7 - usize::from((cmd >> 1) & 0x07)
                    } else {
                        seg.len()
                    };
                    data.extend_from_slice(seg.get(..used)?);
                    if data.len() > size {
                        aborted(abort::LENGTH)
                    } else if last {
                        if data.len() != size {
                            aborted(abort::LENGTH)
                        } else {
                            match od.write(index, sub, &data) {
                                Ok(()) => reply(segment_ack(toggle)),
                                Err(e) => aborted(abort_code(e)),
                            }
                        }
                    } else {
                        server.transfer = Some(Transfer::Download {
                            index,
                            sub,
                            size,
                            data,
                            toggle: !toggle,
                        });
                        reply(segment_ack(toggle))
                    }
                }
                Some(Transfer::Download { .. }) => aborted(abort::TOGGLE),
                _ => aborted(abort::BAD_COMMAND),
            }
        }
        _ => aborted(abort::BAD_COMMAND),
    };
    Some(response)
}

/// A download segment response: scs 1 with the segment's toggle.
fn segment_ack(toggle: bool) -> Vec<u8> {
    let mut p = vec![0x20 | (u8::from(toggle) << 4)];
    p.extend([0u8; 7]);
    p
}

fn write_and_answer(
    od: &mut ObjectDictionary,
    index: u16,
    sub: u8,
    data: &[u8],
    reply: &dyn Fn(Vec<u8>) -> Vec<u8>,
    aborted: &dyn Fn(u32) -> Vec<u8>,
) -> Vec<u8> {
    match od.write(index, sub, data) {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// One request to a fresh server with a 128-byte mailbox.
    fn serve1(od: &mut ObjectDictionary, request: &[u8]) -> Option<Vec<u8>> {
        serve(od, &mut SdoServer::default(), request, 128)
    }

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
        let r = serve1(&mut od, &request(&[0x40, 0x12, 0x1C, 0x00, 0, 0, 0, 0])).unwrap();
        assert_eq!(&sdo_of(&r)[..5], &[0x4F, 0x12, 0x1C, 0x00, 1]);
        let r = serve1(&mut od, &request(&[0x40, 0x12, 0x1C, 0x01, 0, 0, 0, 0])).unwrap();
        assert_eq!(&sdo_of(&r)[..6], &[0x4B, 0x12, 0x1C, 0x01, 0x00, 0x16]);
        let r = serve1(&mut od, &request(&[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0])).unwrap();
        assert_eq!(&sdo_of(&r)[..8], &[0x43, 0x18, 0x10, 0x01, 0xAA, 0, 0, 0]);
    }

    #[test]
    fn downloads_and_aborts() {
        let mut od = ObjectDictionary::cia402_servo(1, 2, 3, 4);
        let r = serve1(&mut od, &request(&[0x2F, 0x60, 0x60, 0x00, 9, 0, 0, 0])).unwrap();
        assert_eq!(sdo_of(&r)[0], 0x60);
        assert_eq!(od.read(0x6060, 0), Ok(&[9u8][..]));
        let abort_of = |r: &[u8]| u32::from_le_bytes(sdo_of(r)[4..8].try_into().unwrap());
        let r = serve1(&mut od, &request(&[0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0])).unwrap();
        assert_eq!(sdo_of(&r)[0], 0x80);
        assert_eq!(abort_of(&r), abort::NO_OBJECT);
        let r = serve1(&mut od, &request(&[0x23, 0x00, 0x10, 0x00, 1, 2, 3, 4])).unwrap();
        assert_eq!(abort_of(&r), abort::READ_ONLY);
        let r = serve1(&mut od, &request(&[0x50, 0x12, 0x1C, 0x00, 0, 0, 0, 0])).unwrap();
        assert_eq!(abort_of(&r), abort::UNSUPPORTED_ACCESS, "complete access");
        let r = serve1(&mut od, &request(&[0xE0, 0x12, 0x1C, 0x00, 0, 0, 0, 0])).unwrap();
        assert_eq!(abort_of(&r), abort::BAD_COMMAND);
    }

    #[test]
    fn aborts_are_sdo_requests_with_the_abort_specifier() {
        let mut od = ObjectDictionary::cia402_servo(1, 2, 3, 4);
        let r = serve1(&mut od, &request(&[0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0])).unwrap();
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
        assert!(serve1(&mut od, &m).is_none());
        assert!(serve1(&mut od, &[1, 2]).is_none());
        let mut huge = request(&[0x40, 0, 0, 0]);
        huge[0] = 0xFF;
        assert!(serve1(&mut od, &huge).is_none());
    }

    /// A raw SDO message (mailbox + CoE headers) with `sdo` as its SDO part.
    fn message(sdo: &[u8]) -> Vec<u8> {
        let mut m = vec![0u8; 128];
        let len = (2 + sdo.len()) as u16;
        m[0..2].copy_from_slice(&len.to_le_bytes());
        m[5] = MAILBOX_TYPE_COE;
        m[6..8].copy_from_slice(&(COE_SDO_REQUEST << 12).to_le_bytes());
        m[8..8 + sdo.len()].copy_from_slice(sdo);
        m
    }

    #[test]
    fn objects_larger_than_the_mailbox_go_in_segments_both_ways() {
        let mut od = ObjectDictionary::cia402_servo(1, 2, 3, 4);
        let long: Vec<u8> = (0..300u32).map(|i| (i % 251) as u8).collect();
        od.insert(0x1008, 0, &long, true);
        let mut server = SdoServer::default();
        // Upload: the initiate answer carries the size and the first 112 bytes.
        let r = serve(
            &mut od,
            &mut server,
            &message(&[0x40, 0x08, 0x10, 0, 0, 0, 0, 0]),
            128,
        )
        .unwrap();
        assert_eq!(r.len(), 128);
        let s = &r[8..];
        assert_eq!(s[0], 0x41);
        assert_eq!(u32::from_le_bytes(s[4..8].try_into().unwrap()), 300);
        let mut got = s[8..].to_vec();
        // Segments with alternating toggles until the last.
        let mut toggle = 0u8;
        loop {
            let r = serve(
                &mut od,
                &mut server,
                &message(&[0x60 | toggle << 4, 0, 0, 0, 0, 0, 0, 0]),
                128,
            )
            .unwrap();
            let len = u16::from_le_bytes([r[0], r[1]]) as usize - 3;
            let cmd = r[8];
            assert_eq!(cmd >> 5, 0, "upload segment response");
            assert_eq!((cmd >> 4) & 1, toggle, "toggle echoed");
            got.extend_from_slice(&r[9..9 + len]);
            if cmd & 1 == 1 {
                break;
            }
            toggle ^= 1;
        }
        assert_eq!(got, long);
        // A wrong toggle aborts with 0x05030000.
        serve(
            &mut od,
            &mut server,
            &message(&[0x40, 0x08, 0x10, 0, 0, 0, 0, 0]),
            128,
        )
        .unwrap();
        let r = serve(
            &mut od,
            &mut server,
            &message(&[0x70, 0, 0, 0, 0, 0, 0, 0]),
            128,
        )
        .unwrap();
        assert_eq!(
            u32::from_le_bytes(r[12..16].try_into().unwrap()),
            abort::TOGGLE
        );

        // Download: initiate with the size and the first bytes, then segments; the last
        // one is short (7 bytes with 3 unused).
        let new: Vec<u8> = (0..300u32).map(|i| (i * 7 % 256) as u8).collect();
        let mut init = vec![0x21, 0x08, 0x10, 0x00];
        init.extend(300u32.to_le_bytes());
        init.extend(&new[..100]);
        let r = serve(&mut od, &mut server, &message(&init), 128).unwrap();
        assert_eq!(r[8], 0x60);
        let mut at = 100;
        let mut toggle = 0u8;
        while at < 300 {
            let chunk = (300 - at).min(96);
            let last = at + chunk == 300;
            let mut seg = vec![toggle << 4 | u8::from(last)];
            seg.extend(&new[at..at + chunk]);
            if chunk < 7 {
                seg[0] |= ((7 - chunk) as u8) << 1;
                seg.resize(8, 0);
            }
            let r = serve(&mut od, &mut server, &message(&seg), 128).unwrap();
            assert_eq!(r[8], 0x20 | toggle << 4, "segment acknowledged");
            at += chunk;
            toggle ^= 1;
        }
        assert_eq!(od.read(0x1008, 0).unwrap(), &new[..]);
        // A segment out of the blue is refused.
        let r = serve(
            &mut od,
            &mut server,
            &message(&[0x00, 1, 2, 3, 4, 5, 6, 7]),
            128,
        )
        .unwrap();
        assert_eq!(
            u32::from_le_bytes(r[12..16].try_into().unwrap()),
            abort::BAD_COMMAND
        );
    }
}
