//! The cyclic frame: the group's process data image, sent as LRW datagrams over the mapped
//! bytes alone, and what that costs on the wire.
//!
//! ethercrab's `SubDeviceGroup::tx_rx` puts an AL-status FPRD per slave beside the LRW
//! (12 B header + 2 B data each: 224 B more at 16 drives). Like IgH and SOEM, gantry
//! supervises with the LRW's working counter instead — a slave that stops answering no
//! longer counts (ETG.1000.4 §5.4.3: an LRW counts +1 for a read, +2 for a write, per
//! slave) — and reads each slave's AL status only when something is wrong, in the next
//! cycle (see `health`).
//!
//! ethercrab's public raw API (`Command::lrw`, `Command::brd`, `Command::frmw`) sends one
//! datagram per frame; the cycle's exchange joins the frames it queues together
//! (`coalesce`). So a steady cycle's frame is the LRW and, when DC runs, the FRMW of the
//! reference clock's time (0x0910, 20 B): one fixed-size datagram whatever the number of
//! slaves. One cycle in `health::AL_STATUS_EVERY` sends a BRD of AL status (0x0130, 14 B)
//! in its place instead — a slave that goes from OP to SafeOp does not change the LRW's
//! count (its SyncManagers stay active in SafeOp, ETG.1000.6 §6.4.1), every slave ORs its
//! state into the BRD.

use std::ops::Range;

use ethercrab::error::Error;
use ethercrab::subdevice_group::HasPdi;
use ethercrab::{Command, MainDevice, SubDeviceGroup};
use thiserror::Error;

/// Logical address the single group's image starts at: ethercrab maps the groups one after
/// the other from 0 (`MainDevice::init`, `PdiOffset::default()`), and gantry has one.
pub const LOGICAL_START: u32 = 0;

/// Ethernet header: destination, source, EtherType (IEEE 802.3).
pub const ETHERNET_HEADER: usize = 14;
/// Frame check sequence (IEEE 802.3).
pub const FCS: usize = 4;
/// Preamble, start-of-frame delimiter and the inter-frame gap: on the wire, not in the frame
/// (IEEE 802.3 §4.4.2: 7 + 1 + 12 bytes).
pub const PREAMBLE_AND_GAP: usize = 20;
/// Smallest Ethernet frame, FCS included (IEEE 802.3 §4.4.2): shorter ones are padded.
pub const MIN_FRAME: usize = 64;
/// EtherCAT frame header: length, type (ETG.1000.4 §5.3.1).
pub const ECAT_HEADER: usize = 2;
/// Datagram header: command, index, address, length, IRQ (ETG.1000.4 §5.4.1).
pub const DATAGRAM_HEADER: usize = 10;
/// Working counter after each datagram's data (ETG.1000.4 §5.4.1).
pub const WORKING_COUNTER: usize = 2;
/// Bytes of DC system time the FRMW carries (register 0x0910, ETG.1000.4 Table 60).
pub const DC_TIME_BYTES: usize = 8;
/// Datagram bytes one frame holds: an Ethernet payload (1500 B) less the EtherCAT header.
pub const MAX_DATAGRAMS: usize = 1500 - ECAT_HEADER;
/// Bytes of AL status the summary BRD reads (register 0x0130, ETG.1000.4 Table 35).
pub const AL_STATUS_BYTES: usize = 2;
/// Bit rate of the wire (100BASE-TX): bits per microsecond.
pub const BITS_PER_US: f64 = 100.0;

/// Bytes one datagram takes in a frame.
pub const fn datagram_bytes(data: usize) -> usize {
    DATAGRAM_HEADER + data + WORKING_COUNTER
}

/// Bytes an Ethernet frame carrying `datagrams` bytes of datagrams takes on the wire:
/// headers, padding to the minimum frame, FCS, preamble and gap.
pub const fn wire_bytes(datagrams: usize) -> usize {
    let frame = ETHERNET_HEADER + ECAT_HEADER + datagrams + FCS;
    let frame = if frame < MIN_FRAME { MIN_FRAME } else { frame };
    frame + PREAMBLE_AND_GAP
}

/// Microseconds `bytes` take on a 100 Mbit/s wire.
pub fn wire_us(bytes: usize) -> f64 {
    bytes as f64 * 8.0 / BITS_PER_US
}

/// Why the image could not be laid out.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum ImageError {
    /// ethercrab's image is not laid out as gantry reads it (all inputs, then all outputs,
    /// each slave's after the one before, from 0).
    #[error(
        "slave {slave}'s {what} are at byte {found} of the process image, not {expected}: \
         the image is not laid out as ethercrab 0.7 maps it"
    )]
    Layout {
        /// The slave.
        slave: usize,
        /// Inputs or outputs.
        what: &'static str,
        /// Where they are.
        found: usize,
        /// Where they should be.
        expected: usize,
    },
    /// More process data than one frame slot takes, in more pieces than gantry sends.
    #[error("{bytes} bytes of process data need more than {MAX_CHUNKS} LRW datagrams")]
    TooLarge {
        /// The image's size.
        bytes: usize,
    },
}

/// Most LRW datagrams per cycle.
pub const MAX_CHUNKS: usize = 8;

/// One slave's bytes in the image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SlaveIo {
    /// Its inputs.
    pub inputs: Range<usize>,
    /// Its outputs.
    pub outputs: Range<usize>,
}

/// One LRW datagram: the bytes it carries and the working counter it comes back with when
/// every slave in it exchanged.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Chunk {
    /// Bytes of the image.
    pub bytes: Range<usize>,
    /// Expected working counter.
    pub working_counter: u16,
}

/// The process data image the cycle reads and writes, as the wire carries it: every
/// slave's inputs (from 0), then every slave's outputs.
#[derive(Clone, Debug)]
pub struct ProcessImage {
    bytes: Box<[u8]>,
    read_len: usize,
    slaves: Vec<SlaveIo>,
    chunks: Vec<Chunk>,
}

/// What one cycle's LRW datagrams said.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LrwReply {
    /// Sum of the working counters.
    pub working_counter: u16,
    /// Every datagram came back with its expected count (the inputs were taken).
    pub complete: bool,
}

impl ProcessImage {
    /// The image for slaves with these (inputs, outputs) byte counts, in chain order, cut in
    /// datagrams of at most `max_datagram` bytes of data.
    pub fn new(sizes: &[(usize, usize)], max_datagram: usize) -> Result<Self, ImageError> {
        let read_len: usize = sizes.iter().map(|s| s.0).sum();
        let len = read_len + sizes.iter().map(|s| s.1).sum::<usize>();
        let (mut at_in, mut at_out) = (0, read_len);
        let slaves: Vec<SlaveIo> = sizes
            .iter()
            .map(|&(i, o)| {
                let io = SlaveIo {
                    inputs: at_in..at_in + i,
                    outputs: at_out..at_out + o,
                };
                (at_in, at_out) = (at_in + i, at_out + o);
                io
            })
            .collect();
        let max = max_datagram.max(1);
        let chunks: Vec<Chunk> = (0..len.div_ceil(max))
            .map(|k| {
                let bytes = k * max..((k + 1) * max).min(len);
                // ETG.1000.4 §5.4.3: per datagram, a slave counts +1 if it read (its
                // inputs are in it) and +2 if it wrote (its outputs are).
                let touches =
                    |r: &Range<usize>| !r.is_empty() && r.start < bytes.end && bytes.start < r.end;
                let working_counter = slaves
                    .iter()
                    .map(|s| u16::from(touches(&s.inputs)) + 2 * u16::from(touches(&s.outputs)))
                    .sum();
                Chunk {
                    bytes,
                    working_counter,
                }
            })
            .collect();
        if chunks.len() > MAX_CHUNKS {
            return Err(ImageError::TooLarge { bytes: len });
        }
        Ok(Self {
            bytes: vec![0; len].into_boxed_slice(),
            read_len,
            slaves,
            chunks,
        })
    }

    /// The image of ethercrab's group, checked against where ethercrab keeps each slave's
    /// bytes (its image must be laid out as [`ProcessImage::new`] lays it out, since the
    /// LRW addresses the slaves' FMMUs by those offsets).
    pub fn of_group<const N: usize, const P: usize, S: HasPdi, DC>(
        group: &SubDeviceGroup<N, P, ethercrab::DefaultLock, S, DC>,
        md: &MainDevice<'_>,
        max_datagram: usize,
    ) -> Result<Self, ImageError> {
        // Where each slave's bytes are in ethercrab's own image (addresses in one array).
        let spans: Vec<((usize, usize), (usize, usize))> = group
            .iter(md)
            .map(|sd| {
                let io = sd.io_raw();
                let (i, o) = (io.inputs(), io.outputs());
                (
                    (i.as_ptr() as usize, i.len()),
                    (o.as_ptr() as usize, o.len()),
                )
            })
            .collect();
        let sizes: Vec<(usize, usize)> = spans.iter().map(|&(i, o)| (i.1, o.1)).collect();
        let image = Self::new(&sizes, max_datagram)?;
        // The first slave with any bytes has them at offset 0 (its inputs, or if no slave
        // has inputs, its outputs).
        let base = spans
            .iter()
            .flat_map(|&(i, o)| [i, o])
            .filter(|s| s.1 > 0)
            .map(|s| s.0)
            .min();
        if let Some(base) = base {
            for (slave, (&(i, o), io)) in spans.iter().zip(&image.slaves).enumerate() {
                for (what, (ptr, len), expected) in [
                    ("inputs", i, io.inputs.start),
                    ("outputs", o, io.outputs.start),
                ] {
                    let found = ptr.wrapping_sub(base);
                    if len > 0 && found != expected {
                        return Err(ImageError::Layout {
                            slave,
                            what,
                            found,
                            expected,
                        });
                    }
                }
            }
        }
        Ok(image)
    }

    /// Slave `i`'s inputs (empty if there is no such slave).
    pub fn inputs(&self, i: usize) -> &[u8] {
        self.slaves
            .get(i)
            .and_then(|s| self.bytes.get(s.inputs.clone()))
            .unwrap_or_default()
    }

    /// Slave `i`'s outputs as the next exchange sends them (empty if there is no such
    /// slave).
    pub fn outputs(&self, i: usize) -> &[u8] {
        self.slaves
            .get(i)
            .and_then(|s| self.bytes.get(s.outputs.clone()))
            .unwrap_or_default()
    }

    /// Slave `i`'s outputs (empty if there is no such slave).
    pub fn outputs_mut(&mut self, i: usize) -> &mut [u8] {
        match self.slaves.get(i) {
            Some(s) => self.bytes.get_mut(s.outputs.clone()).unwrap_or_default(),
            None => &mut [],
        }
    }

    /// The LRW datagrams of a cycle.
    pub fn chunks(&self) -> &[Chunk] {
        &self.chunks
    }

    /// Slaves in the image, in chain order (those without process data too).
    pub fn slaves(&self) -> usize {
        self.slaves.len()
    }

    /// Bytes of the image (inputs and outputs).
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    /// Whether no slave has process data.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// What each slave adds to the working counter of the image's datagrams when it
    /// exchanges (in chain order; allocates: for the bring-up).
    pub fn slave_working_counters(&self) -> Vec<u16> {
        (0..self.slaves.len())
            .map(|i| self.slave_working_counter(i))
            .collect()
    }

    /// What slave `i` adds to the working counter of the image's datagrams: per datagram
    /// its inputs are in, 1; its outputs, 2 (ETG.1000.4 §5.4.3).
    pub fn slave_working_counter(&self, i: usize) -> u16 {
        let Some(s) = self.slaves.get(i) else {
            return 0;
        };
        let touches = |r: &Range<usize>, c: &Chunk| {
            !r.is_empty() && r.start < c.bytes.end && c.bytes.start < r.end
        };
        self.chunks
            .iter()
            .map(|c| u16::from(touches(&s.inputs, c)) + 2 * u16::from(touches(&s.outputs, c)))
            .sum()
    }

    /// Working counter of the whole image when every slave exchanged.
    pub fn expected_working_counter(&self) -> u16 {
        self.chunks.iter().map(|c| c.working_counter).sum()
    }

    /// Bytes on the wire per cycle: the LRW frames, plus `extra` bytes of fixed-size
    /// datagrams (the AL-status BRD, the DC FRMW; see [`datagram_bytes`]) joined to the
    /// first LRW's frame when they fit there (as the cycle's exchange joins them), else in a frame of
    /// their own.
    pub fn wire_bytes(&self, extra: usize) -> usize {
        let mut frames: Vec<usize> = self
            .chunks
            .iter()
            .map(|c| datagram_bytes(c.bytes.len()))
            .collect();
        if extra > 0 {
            match frames.first_mut() {
                Some(first) if *first + extra <= MAX_DATAGRAMS => *first += extra,
                _ => frames.push(extra),
            }
        }
        frames.into_iter().map(wire_bytes).sum()
    }

    /// The least any master sends for this image: the mapped bytes in as few full-size
    /// frames as an Ethernet MTU (1500 B) allows, one datagram each.
    pub fn minimum_wire_bytes(&self) -> usize {
        const PER_FRAME: usize = MAX_DATAGRAMS - DATAGRAM_HEADER - WORKING_COUNTER;
        let len = self.bytes.len();
        let frames = len.div_ceil(PER_FRAME).max(1);
        (0..frames)
            .map(|k| wire_bytes(datagram_bytes((len - k * PER_FRAME).min(PER_FRAME))))
            .sum()
    }

    /// Sends the image's LRW datagrams (one frame each, one after the other) and takes the
    /// inputs of every datagram that came back complete. A datagram with a wrong working
    /// counter leaves its inputs as they were (the bus then reads the slaves' states and
    /// their inputs with ethercrab's `tx_rx` next cycle). No allocation: the frames are
    /// ethercrab's preallocated ones.
    pub async fn exchange(&mut self, md: &MainDevice<'_>) -> Result<LrwReply, Error> {
        let mut reply = LrwReply {
            working_counter: 0,
            complete: true,
        };
        for chunk in &self.chunks {
            let range = chunk.bytes.clone();
            let sent = self.bytes.get(range.clone()).ok_or(Error::Internal)?;
            let address = LOGICAL_START + range.start as u32;
            let answer = Command::lrw(address)
                .with_wkc(chunk.working_counter)
                .send_receive_slice(md, sent)
                .await;
            match answer {
                Ok(data) => {
                    reply.working_counter += chunk.working_counter;
                    // Only the inputs come back changed (the outputs are ours).
                    let inputs = range.start..range.end.min(self.read_len);
                    if let (Some(dst), Some(src)) = (
                        self.bytes.get_mut(inputs.clone()),
                        data.get(..inputs.len().min(data.len())),
                    ) {
                        if dst.len() == src.len() {
                            dst.copy_from_slice(src);
                        }
                    }
                }
                Err(Error::WorkingCounter { received, .. }) => {
                    reply.working_counter += received;
                    reply.complete = false;
                }
                Err(e) => return Err(e),
            }
        }
        Ok(reply)
    }

    /// Copies the outputs into ethercrab's image of `group` (before its `tx_rx`).
    pub fn put_outputs<const N: usize, const P: usize, S: HasPdi, DC>(
        &self,
        group: &SubDeviceGroup<N, P, ethercrab::DefaultLock, S, DC>,
        md: &MainDevice<'_>,
    ) {
        for (sd, io) in group.iter(md).zip(&self.slaves) {
            let mut out = sd.outputs_raw_mut();
            if let Some(src) = self.bytes.get(io.outputs.clone()) {
                if out.len() == src.len() {
                    out.copy_from_slice(src);
                }
            }
        }
    }

    /// Copies the inputs of the slaves `fresh` names from ethercrab's image of `group`
    /// (after its `tx_rx`; a slave that did not exchange comes back with whatever
    /// ethercrab last had, which may be from its last `tx_rx` long ago).
    pub fn take_inputs<const N: usize, const P: usize, S: HasPdi, DC>(
        &mut self,
        group: &SubDeviceGroup<N, P, ethercrab::DefaultLock, S, DC>,
        md: &MainDevice<'_>,
        fresh: impl Fn(usize) -> bool,
    ) {
        for (i, (sd, io)) in group.iter(md).zip(&self.slaves).enumerate() {
            if !fresh(i) {
                continue;
            }
            let inputs = sd.inputs_raw();
            if let Some(dst) = self.bytes.get_mut(io.inputs.clone()) {
                if dst.len() == inputs.len() {
                    dst.copy_from_slice(&inputs);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_image_is_all_inputs_then_all_outputs_and_counts_per_datagram() {
        let image = ProcessImage::new(&[(4, 2), (0, 3), (5, 0)], 1000).unwrap();
        assert_eq!(image.len(), 14);
        assert_eq!(image.slaves[1].outputs, 11..14);
        assert_eq!(image.slaves[2].inputs, 4..9);
        assert_eq!(image.expected_working_counter(), 3 + 2 + 1);
        // Cut in datagrams of 5: inputs of 0 (0..4) in the first, of 2 (4..9) in the first
        // two; outputs of 0 (9..11) in the second and third, of 1 (11..14) in the third.
        let image = ProcessImage::new(&[(4, 2), (0, 3), (5, 0)], 5).unwrap();
        let counts: Vec<u16> = image.chunks().iter().map(|c| c.working_counter).collect();
        assert_eq!(counts, [1 + 1, 1 + 2, 2 + 2]);
        // Per slave: 0 reads in the first datagram, writes in the second and third; 1
        // writes in the third; 2 reads in the first two.
        assert_eq!(image.slave_working_counters(), [1 + 2 + 2, 2, 1 + 1]);
        assert_eq!(
            image.slave_working_counters().iter().sum::<u16>(),
            image.expected_working_counter()
        );
        assert!(matches!(
            ProcessImage::new(&[(100, 0)], 10),
            Err(ImageError::TooLarge { bytes: 100 })
        ));
    }

    #[test]
    fn wire_bytes_pad_short_frames_and_count_preamble_and_gap() {
        // An LRW of 10 bytes: 14 + 2 + 22 + 4 = 42, padded to 64, + 20.
        assert_eq!(wire_bytes(datagram_bytes(10)), 84);
        // 1486 bytes of data fill a 1514-byte frame: + FCS + preamble/gap.
        assert_eq!(wire_bytes(datagram_bytes(1486)), 1518 + 20);
        assert!((wire_us(1250) - 100.0).abs() < 1e-9);
        let image = ProcessImage::new(&[(20, 20); 64], 1486).unwrap();
        assert_eq!(image.minimum_wire_bytes(), image.wire_bytes(0));
        // 2560 bytes: two full-ish frames; the FRMW joins the first only if it fits.
        let two = image.wire_bytes(0);
        assert_eq!(image.wire_bytes(20), two + 84, "the first frame is full");
        let image = ProcessImage::new(&[(11, 11); 16], 1486).unwrap();
        assert_eq!(image.wire_bytes(20 + 14), image.wire_bytes(0) + 34);
    }
}
