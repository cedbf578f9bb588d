//! The two halves of an SDO block transfer (CiA 301 §7.2.4.3.9–.16) shared by client and
//! server: the sender of sub-blocks (client in download, server in upload) and their
//! receiver (server in download, client in upload).
//!
//! A transfer is a run of 7-byte segments, at least one (a 0-byte transfer sends one empty
//! segment with `c` set); a sub-block is up to `blksize` of them numbered from 1. The
//! receiver confirms each sub-block with the last sequence number it got in order
//! (`ackseq`); the sender continues with the segment after it, in a new sub-block numbered
//! from 1 again — so a lost segment is sent again, and so are the ones after it.
//!
//! Both halves keep the block CRC (§7.2.4.3.16) as the transfer goes, over the segments
//! as they are confirmed (sender) or stored in order (receiver): the end frame costs no
//! pass over the whole buffer, so no step of a transfer does more work than its segments.

use super::abort::AbortCode;
use super::command::{BlockSegment, MAX_BLOCK_SIZE, SEGMENT_DATA};
use super::crc::Crc16;

/// Segments needed for `len` bytes (at least one).
pub(crate) const fn segments_for(len: usize) -> usize {
    if len == 0 {
        1
    } else {
        len.div_ceil(SEGMENT_DATA)
    }
}

/// Checks a block size of a received frame (CiA 301: 1..=127, else 0x05040002).
pub(crate) const fn check_block_size(blksize: u8) -> Result<u8, AbortCode> {
    if blksize == 0 || blksize > MAX_BLOCK_SIZE {
        Err(AbortCode::INVALID_BLOCK_SIZE)
    } else {
        Ok(blksize)
    }
}

/// Sends `len` bytes of a buffer in sub-blocks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct BlockSender {
    len: usize,
    total: usize,
    /// Segments the receiver has confirmed.
    confirmed: usize,
    blksize: u8,
    /// Sequence number of the next segment to send in this sub-block (1-based).
    next_seq: u8,
    /// Whether segments of the current sub-block remain to be sent.
    sending: bool,
    /// CRC of the confirmed segments' data.
    crc: Crc16,
}

/// What an acknowledgement means to the sender.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum AckResult {
    /// More to send: a new sub-block has started.
    More,
    /// Every segment is confirmed: send the end frame.
    Done,
}

impl BlockSender {
    pub(crate) fn new(len: usize, blksize: u8) -> Self {
        Self {
            len,
            total: segments_for(len),
            confirmed: 0,
            blksize,
            next_seq: 1,
            sending: true,
            crc: Crc16::new(),
        }
    }

    /// The next segment of the current sub-block, if any remain before an ack is due.
    pub(crate) fn next_segment(&mut self, buf: &[u8]) -> Option<BlockSegment> {
        if !self.sending {
            return None;
        }
        let k = self.confirmed + self.next_seq as usize - 1;
        if k >= self.total {
            self.sending = false;
            return None;
        }
        let start = k * SEGMENT_DATA;
        let end = (start + SEGMENT_DATA).min(self.len);
        let mut data = [0u8; SEGMENT_DATA];
        if let Some(src) = buf.get(start..end) {
            for (d, s) in data.iter_mut().zip(src) {
                *d = *s;
            }
        }
        let last = k + 1 == self.total;
        let seg = BlockSegment {
            seqno: self.next_seq,
            last,
            data,
        };
        if last || self.next_seq >= self.blksize {
            self.sending = false;
        } else {
            self.next_seq += 1;
        }
        Some(seg)
    }

    /// Whether the next segment (if one remains to be sent) ends its sub-block: the
    /// receiver answers it.
    pub(crate) fn next_ends_sub_block(&self) -> bool {
        let k = self.confirmed + self.next_seq as usize - 1;
        self.sending && (k + 1 >= self.total || self.next_seq >= self.blksize)
    }

    /// Segments sent in the current sub-block.
    fn sent_in_sub_block(&self) -> u8 {
        if self.sending {
            self.next_seq - 1
        } else {
            // The last segment sent keeps its number when sending stops.
            self.next_seq
        }
    }

    /// Takes the receiver's acknowledgement (`buf`: the data being sent, whose newly
    /// confirmed segments go into the CRC). An `ackseq` past what was sent is 0x05040003,
    /// a block size outside 1..=127 is 0x05040002.
    pub(crate) fn on_ack(
        &mut self,
        ackseq: u8,
        blksize: u8,
        buf: &[u8],
    ) -> Result<AckResult, AbortCode> {
        if ackseq > self.sent_in_sub_block() {
            return Err(AbortCode::INVALID_SEQUENCE_NUMBER);
        }
        let blksize = check_block_size(blksize)?;
        let from = (self.confirmed * SEGMENT_DATA).min(self.len);
        self.confirmed += ackseq as usize;
        let to = (self.confirmed * SEGMENT_DATA).min(self.len);
        self.crc.update(buf.get(from..to).unwrap_or(&[]));
        if self.confirmed >= self.total {
            self.sending = false;
            return Ok(AckResult::Done);
        }
        self.blksize = blksize;
        self.next_seq = 1;
        self.sending = true;
        Ok(AckResult::More)
    }

    /// Bytes of the last segment that carry no data (`n` of the end frame).
    pub(crate) fn unused_in_last(&self) -> u8 {
        (self.total * SEGMENT_DATA - self.len) as u8
    }

    /// The CRC of the data confirmed so far (all of it once [`AckResult::Done`]).
    pub(crate) fn crc(&self) -> u16 {
        self.crc.value()
    }
}

/// Receives sub-blocks into a buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct BlockReceiver {
    blksize: u8,
    /// Last sequence number received in order in the current sub-block.
    ackseq: u8,
    /// Segments stored (7 bytes each, the last one partly).
    segments: usize,
    /// The segment with `c` arrived in order.
    done: bool,
    /// A segment of the current sub-block arrived since the last ack.
    in_sub_block: bool,
    /// CRC of the segments stored, all but the last one (whose unused bytes only the end
    /// frame tells).
    crc: Crc16,
}

impl BlockReceiver {
    pub(crate) fn new(blksize: u8) -> Self {
        Self {
            blksize,
            ackseq: 0,
            segments: 0,
            done: false,
            in_sub_block: false,
            crc: Crc16::new(),
        }
    }

    /// Segments stored in order so far.
    pub(crate) fn segments(&self) -> usize {
        self.segments
    }

    /// Whether the last segment has arrived (the end frame is next).
    pub(crate) fn is_done(&self) -> bool {
        self.done
    }

    /// Takes a segment. Returns the `ackseq` to acknowledge when the sub-block is over
    /// (its last sequence number or the `c` segment arrived, in order or not). A sequence
    /// number past the block size is 0x05040003; data past the buffer is 0x05040005.
    /// Segments out of order (one before them was lost) are dropped, to be sent again.
    pub(crate) fn on_segment(
        &mut self,
        seg: &BlockSegment,
        buf: &mut [u8],
    ) -> Result<Option<u8>, AbortCode> {
        if seg.seqno > self.blksize {
            return Err(AbortCode::INVALID_SEQUENCE_NUMBER);
        }
        if self.done {
            // Nothing may follow the last segment but the end frame.
            return Err(AbortCode::INVALID_SEQUENCE_NUMBER);
        }
        self.in_sub_block = true;
        if seg.seqno == self.ackseq + 1 {
            let start = self.segments * SEGMENT_DATA;
            if start >= buf.len() && !(seg.last && start == buf.len()) {
                return Err(AbortCode::OUT_OF_MEMORY);
            }
            let end = (start + SEGMENT_DATA).min(buf.len());
            if let Some(dst) = buf.get_mut(start..end) {
                for (d, s) in dst.iter_mut().zip(seg.data) {
                    *d = s;
                }
            }
            if !seg.last {
                self.crc.update(&seg.data);
            }
            self.segments += 1;
            self.ackseq = seg.seqno;
            if seg.last {
                self.done = true;
            }
        }
        if seg.last || seg.seqno == self.blksize {
            return Ok(Some(self.take_ack()));
        }
        Ok(None)
    }

    /// The ack to send when segments stopped coming mid-sub-block (the last ones were
    /// lost); None if no sub-block is in progress.
    pub(crate) fn on_silence(&mut self) -> Option<u8> {
        if self.in_sub_block && !self.done {
            Some(self.take_ack())
        } else {
            None
        }
    }

    fn take_ack(&mut self) -> u8 {
        let ack = self.ackseq;
        self.ackseq = 0;
        self.in_sub_block = false;
        ack
    }

    /// The block size to announce in the ack.
    pub(crate) fn block_size(&self) -> u8 {
        self.blksize
    }

    /// The transfer's length once the end frame gives `unused` (bytes of the last segment
    /// without data, 0..=7).
    pub(crate) fn length(&self, unused: u8) -> Option<usize> {
        (self.segments * SEGMENT_DATA).checked_sub(unused as usize)
    }

    /// The CRC of the `len` bytes received into `buf` (`len` from [`Self::length`]): the
    /// running CRC and the last segment's bytes that carry data.
    pub(crate) fn crc(&self, buf: &[u8], len: usize) -> u16 {
        let mut crc = self.crc;
        let last = self.segments.saturating_sub(1) * SEGMENT_DATA;
        crc.update(buf.get(last.min(len)..len).unwrap_or(&[]));
        crc.value()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sender_resends_from_the_segment_after_ackseq() {
        let data: Vec<u8> = (0..30).collect(); // 5 segments, the last with 2 bytes
        let mut s = BlockSender::new(data.len(), 3);
        let first: Vec<_> = std::iter::from_fn(|| s.next_segment(&data)).collect();
        assert_eq!(first.iter().map(|g| g.seqno).collect::<Vec<_>>(), [1, 2, 3]);
        // Segment 2 lost: the receiver confirms 1.
        assert_eq!(s.on_ack(1, 3, &data), Ok(AckResult::More));
        let second: Vec<_> = std::iter::from_fn(|| s.next_segment(&data)).collect();
        assert_eq!(second.len(), 3);
        assert_eq!(second[0].seqno, 1);
        assert_eq!(
            second[0].data[0], 7,
            "resends the second segment of the transfer"
        );
        assert_eq!(s.on_ack(3, 3, &data), Ok(AckResult::More));
        let third: Vec<_> = std::iter::from_fn(|| s.next_segment(&data)).collect();
        assert_eq!(third.len(), 1);
        assert!(third[0].last);
        assert_eq!(&third[0].data[..2], &[28, 29]);
        assert_eq!(
            s.on_ack(2, 3, &data),
            Err(AbortCode::INVALID_SEQUENCE_NUMBER)
        );
        assert_eq!(s.on_ack(1, 0, &data), Err(AbortCode::INVALID_BLOCK_SIZE));
        assert_eq!(s.on_ack(1, 3, &data), Ok(AckResult::Done));
        assert_eq!(s.unused_in_last(), 5);
    }

    #[test]
    fn receiver_drops_out_of_order_segments() {
        let mut buf = [0u8; 21];
        let mut r = BlockReceiver::new(3);
        let seg = |seqno, last| BlockSegment {
            seqno,
            last,
            data: [seqno; 7],
        };
        assert_eq!(r.on_segment(&seg(1, false), &mut buf), Ok(None));
        assert_eq!(r.on_segment(&seg(3, false), &mut buf), Ok(Some(1)));
        assert_eq!(r.on_segment(&seg(1, false), &mut buf), Ok(None));
        assert_eq!(r.on_silence(), Some(1));
        assert_eq!(r.on_silence(), None);
        assert_eq!(r.on_segment(&seg(1, true), &mut buf), Ok(Some(1)));
        assert!(r.is_done());
        assert_eq!(r.length(3), Some(18));
        assert_eq!(
            r.on_segment(&seg(4, false), &mut buf),
            Err(AbortCode::INVALID_SEQUENCE_NUMBER)
        );
    }

    /// The CRC both halves keep as segments are confirmed or stored is the CRC of the
    /// whole data, whatever was lost and sent again on the way.
    #[test]
    fn the_running_crc_is_the_crc_of_the_data() {
        use super::super::crc::Crc16;
        for len in [0usize, 1, 6, 7, 8, 20, 21, 22, 889, 1000] {
            let data: Vec<u8> = (0..len).map(|i| (i * 31 + 7) as u8).collect();
            let mut s = BlockSender::new(len, 4);
            let mut r = BlockReceiver::new(4);
            let mut buf = vec![0u8; len];
            let mut round = 0;
            loop {
                round += 1;
                let segs: Vec<_> = std::iter::from_fn(|| s.next_segment(&data)).collect();
                let mut ack = None;
                for (k, seg) in segs.iter().enumerate() {
                    // Every third round loses its second segment.
                    if round % 3 == 0 && k == 1 {
                        continue;
                    }
                    ack = r.on_segment(seg, &mut buf).unwrap().or(ack);
                }
                let ack = ack.or_else(|| r.on_silence()).unwrap();
                if s.on_ack(ack, 4, &data).unwrap() == AckResult::Done {
                    break;
                }
            }
            let unused = s.unused_in_last();
            assert_eq!(r.length(unused), Some(len));
            assert_eq!(buf, data, "{len} bytes");
            assert_eq!(s.crc(), Crc16::of(&data), "sender, {len} bytes");
            assert_eq!(r.crc(&buf, len), Crc16::of(&data), "receiver, {len} bytes");
        }
    }

    #[test]
    fn zero_length_is_one_empty_segment() {
        let mut s = BlockSender::new(0, 127);
        let seg = s.next_segment(&[]).unwrap();
        assert!(seg.last);
        assert_eq!(s.next_segment(&[]), None);
        assert_eq!(s.unused_in_last(), 7);
        let mut r = BlockReceiver::new(127);
        assert_eq!(r.on_segment(&seg, &mut []), Ok(Some(1)));
        assert_eq!(r.length(7), Some(0));
    }
}
