//! Frames ethercrab queued together, sent as one Ethernet frame, and the reply split back
//! into one reply per frame. ethercrab 0.7.1's public API (`Command`) puts one datagram in
//! a frame of its own; an EtherCAT frame carries any number of datagrams, each saying
//! whether another follows (ETG.1000.4 §5.3, §5.4.1: bit 15 of the length word, "M"), and
//! the slaves serve them one after the other as the frame passes. So the cycle's LRW and
//! the DC FRMW, queued together, go on the wire as one frame: a datagram more, not a
//! frame more (20 B instead of 84 B on the wire).
//!
//! ethercrab finds the frame a reply belongs to by its first datagram's index
//! (`PduRx::receive_frame`), so each part of the reply goes back as the frame that was
//! queued: the reply's Ethernet header, an EtherCAT header of the part's length, and the
//! part's datagrams with the last one's "more" bit cleared.
//!
//! Everything here works in buffers made at start: the cycle's exchange
//! (`link::FrameIo::exchange`) sends and receives without allocating. It sends what one
//! poll of the cycle's futures queued, so those frames always leave together.

/// Largest Ethernet frame without FCS (IEEE 802.3: 1500 B payload).
pub const MAX_FRAME: usize = 1514;
/// Ethernet header.
const ETH: usize = 14;
/// Ethernet and EtherCAT headers.
const HEADERS: usize = ETH + 2;
/// Datagram header and working counter.
const DATAGRAM_OVERHEAD: usize = 12;
/// "More datagrams follow" (ETG.1000.4 Table 13).
const MORE: u16 = 0x8000;
/// EtherCAT frame type "datagrams" in the EtherCAT header (ETG.1000.4 Table 11).
const TYPE_DATAGRAMS: u16 = 0x1000;
/// Most frames joined into one.
pub const MAX_PARTS: usize = 8;
/// Joined frames in flight whose replies may still come.
const IN_FLIGHT: usize = 8;

/// A frame made of several: the first datagram's index, and each part's datagram bytes.
#[derive(Clone, Copy, Debug, Default)]
struct Joined {
    index: u8,
    parts: [usize; MAX_PARTS],
    count: usize,
}

/// Joins queued frames, splits their replies.
#[derive(Debug)]
pub struct Coalescer {
    out: Vec<u8>,
    /// Where the last datagram of `out` starts (its "more" bit is set when one is added).
    last_at: usize,
    current: Joined,
    in_flight: [Option<Joined>; IN_FLIGHT],
    next_slot: usize,
    scratch: Vec<u8>,
}

impl Default for Coalescer {
    fn default() -> Self {
        Self {
            out: Vec::with_capacity(MAX_FRAME),
            last_at: 0,
            current: Joined::default(),
            in_flight: [None; IN_FLIGHT],
            next_slot: 0,
            scratch: Vec::with_capacity(MAX_FRAME),
        }
    }
}

/// The datagram bytes of an EtherCAT frame and where its last datagram starts (`None`: not
/// an EtherCAT frame gantry can join).
fn datagrams(frame: &[u8]) -> Option<(usize, usize)> {
    if frame.get(12..14)? != [0x88, 0xA4] {
        return None;
    }
    let header = u16::from_le_bytes([*frame.get(ETH)?, *frame.get(ETH + 1)?]);
    let len = usize::from(header & 0x07FF);
    frame.get(HEADERS..HEADERS + len)?;
    let mut at = 0;
    loop {
        let word = frame.get(HEADERS + at + 6..HEADERS + at + 8)?;
        let word = u16::from_le_bytes([word[0], word[1]]);
        let next = at + DATAGRAM_OVERHEAD + usize::from(word & 0x07FF);
        if word & MORE == 0 || next >= len {
            return (next <= len).then_some((len, at));
        }
        at = next;
    }
}

impl Coalescer {
    /// Adds a frame ethercrab queued; `false` when it does not fit beside those already
    /// added (send those first), or is not one to join (send it alone).
    pub fn push(&mut self, frame: &[u8]) -> bool {
        let Some((len, last)) = datagrams(frame) else {
            return false;
        };
        if self.current.count == 0 {
            self.out.clear();
            self.out.extend_from_slice(&frame[..HEADERS + len]);
            self.last_at = HEADERS + last;
        } else {
            if self.current.count >= MAX_PARTS || self.out.len() + len > MAX_FRAME {
                return false;
            }
            let word_at = self.last_at + 6;
            let word = u16::from_le_bytes([self.out[word_at], self.out[word_at + 1]]) | MORE;
            self.out[word_at..word_at + 2].copy_from_slice(&word.to_le_bytes());
            self.last_at = self.out.len() + last;
            self.out.extend_from_slice(&frame[HEADERS..HEADERS + len]);
            let total = (self.out.len() - HEADERS) as u16 | TYPE_DATAGRAMS;
            self.out[ETH..HEADERS].copy_from_slice(&total.to_le_bytes());
        }
        self.current.parts[self.current.count] = len;
        self.current.count += 1;
        true
    }

    /// Whether no frame is waiting.
    pub fn is_empty(&self) -> bool {
        self.current.count == 0
    }

    /// The frame to send (then call [`Coalescer::sent`]).
    pub fn frame(&self) -> &[u8] {
        &self.out
    }

    /// The frame went out: remember how to split its reply.
    pub fn sent(&mut self) {
        self.current.index = self.out.get(HEADERS + 1).copied().unwrap_or(0);
        // A joined frame whose reply never came (lost) must not split the reply of a
        // later frame that starts with the same index (ethercrab's indices wrap at 256).
        for slot in &mut self.in_flight {
            if slot.is_some_and(|j| j.index == self.current.index) {
                *slot = None;
            }
        }
        if self.current.count > 1 {
            self.in_flight[self.next_slot] = Some(self.current);
            self.next_slot = (self.next_slot + 1) % IN_FLIGHT;
        }
        self.current = Joined::default();
        self.out.clear();
    }

    /// Hands `reply` to `each`, split into the replies of the frames that were joined.
    pub fn split(&mut self, reply: &[u8], mut each: impl FnMut(&[u8])) {
        let index = reply.get(HEADERS + 1).copied();
        let slot = self
            .in_flight
            .iter()
            .position(|j| j.is_some_and(|j| Some(j.index) == index));
        let (Some(slot), Some((len, _))) = (slot, datagrams(reply)) else {
            each(reply);
            return;
        };
        let Some(joined) = self.in_flight[slot].take() else {
            return;
        };
        let mut at = HEADERS;
        for &part in joined.parts.iter().take(joined.count) {
            if at + part > HEADERS + len {
                return;
            }
            self.scratch.clear();
            self.scratch.extend_from_slice(&reply[..ETH]);
            self.scratch
                .extend_from_slice(&(part as u16 | TYPE_DATAGRAMS).to_le_bytes());
            self.scratch.extend_from_slice(&reply[at..at + part]);
            // The part's last datagram: no more follow in its own frame.
            if let Some((_, last)) = datagrams(&self.scratch) {
                let word_at = HEADERS + last + 6;
                let word = u16::from_le_bytes([self.scratch[word_at], self.scratch[word_at + 1]]);
                self.scratch[word_at..word_at + 2].copy_from_slice(&(word & !MORE).to_le_bytes());
            }
            each(&self.scratch);
            at += part;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame of one datagram: command, index, `data`, working counter 0.
    fn frame(command: u8, index: u8, data: &[u8]) -> Vec<u8> {
        let mut f = vec![0xFF; 6];
        f.extend_from_slice(&[0x10; 6]);
        f.extend_from_slice(&[0x88, 0xA4]);
        let len = (DATAGRAM_OVERHEAD + data.len()) as u16 | TYPE_DATAGRAMS;
        f.extend_from_slice(&len.to_le_bytes());
        f.extend_from_slice(&[command, index, 0, 0, 0, 0]);
        f.extend_from_slice(&(data.len() as u16).to_le_bytes());
        f.extend_from_slice(&[0, 0]);
        f.extend_from_slice(data);
        f.extend_from_slice(&[0, 0]);
        f
    }

    #[test]
    fn two_frames_go_as_one_and_their_reply_comes_back_as_two() {
        let (lrw, frmw) = (frame(12, 7, &[1, 2, 3]), frame(14, 8, &[0; 8]));
        let mut c = Coalescer::default();
        assert!(c.push(&lrw) && c.push(&frmw));
        let joined = c.frame().to_vec();
        assert_eq!(joined.len(), HEADERS + 15 + 20);
        assert_eq!(
            u16::from_le_bytes([joined[14], joined[15]]),
            35 | TYPE_DATAGRAMS
        );
        // The first datagram now says another follows; the second does not.
        assert_eq!(u16::from_le_bytes([joined[22], joined[23]]), 3 | MORE);
        assert_eq!(u16::from_le_bytes([joined[37], joined[38]]), 8);
        c.sent();
        // The slaves answer (working counters set); the reply is split as sent.
        let mut reply = joined.clone();
        reply[6] = 0x12;
        reply[HEADERS + 15 - 2] = 3;
        let mut parts = Vec::new();
        c.split(&reply, |p| parts.push(p.to_vec()));
        let mut lrw_reply = lrw.clone();
        lrw_reply[6] = 0x12;
        lrw_reply[lrw.len() - 2] = 3;
        let mut frmw_reply = frmw.clone();
        frmw_reply[6] = 0x12;
        assert_eq!(parts, [lrw_reply, frmw_reply]);
        // A reply to a frame sent alone passes as it is.
        let mut one = Vec::new();
        c.split(&lrw, |p| one.push(p.to_vec()));
        assert_eq!(one, std::slice::from_ref(&lrw));
        // A joined frame whose reply was lost: a later frame sent alone with the same
        // first index gets its reply whole.
        assert!(c.push(&lrw) && c.push(&frmw));
        c.sent();
        assert!(c.push(&lrw));
        c.sent();
        let mut one = Vec::new();
        c.split(&lrw, |p| one.push(p.to_vec()));
        assert_eq!(one, [lrw]);
    }

    #[test]
    fn a_frame_that_does_not_fit_is_refused() {
        let big = frame(12, 1, &[0; 1400]);
        let mut c = Coalescer::default();
        assert!(c.push(&big));
        assert!(!c.push(&frame(14, 2, &[0; 100])));
        assert!(!c.push(&[0u8; 10]), "not an EtherCAT frame");
    }
}
