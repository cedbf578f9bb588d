//! A pcap (libpcap "classic") writer for EtherCAT frames, so Wireshark/tshark can dissect
//! what the master sent and received. The format is small enough to write directly:
//! a 24-byte global header (link type 1, Ethernet), then per frame a 16-byte record header
//! (seconds, microseconds, captured length, original length) and the frame.

use std::io::Write;

use thiserror::Error;

/// pcap magic number (microsecond timestamps), written in native order as readers expect.
pub const MAGIC: u32 = 0xA1B2_C3D4;
/// Link type: Ethernet.
pub const LINKTYPE_ETHERNET: u32 = 1;
/// Largest frame kept whole.
pub const SNAPLEN: u32 = 65_535;

/// Writing a capture failed.
#[derive(Debug, Error)]
#[error("cannot write pcap")]
pub struct PcapError(#[from] std::io::Error);

/// Writes frames to a pcap stream.
#[derive(Debug)]
pub struct PcapWriter<W: Write> {
    out: W,
}

impl<W: Write> PcapWriter<W> {
    /// Writes the global header.
    pub fn new(mut out: W) -> Result<Self, PcapError> {
        out.write_all(&MAGIC.to_le_bytes())?;
        out.write_all(&2u16.to_le_bytes())?;
        out.write_all(&4u16.to_le_bytes())?;
        out.write_all(&0i32.to_le_bytes())?; // this zone
        out.write_all(&0u32.to_le_bytes())?; // sigfigs
        out.write_all(&SNAPLEN.to_le_bytes())?;
        out.write_all(&LINKTYPE_ETHERNET.to_le_bytes())?;
        Ok(Self { out })
    }

    /// Writes one frame captured `time_us` microseconds after the epoch of the capture.
    pub fn frame(&mut self, time_us: u64, data: &[u8]) -> Result<(), PcapError> {
        let len = data.len().min(SNAPLEN as usize);
        self.out
            .write_all(&((time_us / 1_000_000) as u32).to_le_bytes())?;
        self.out
            .write_all(&((time_us % 1_000_000) as u32).to_le_bytes())?;
        self.out.write_all(&(len as u32).to_le_bytes())?;
        self.out.write_all(&(data.len() as u32).to_le_bytes())?;
        self.out.write_all(data.get(..len).unwrap_or(data))?;
        Ok(())
    }

    /// Flushes and returns the stream.
    pub fn finish(mut self) -> Result<W, PcapError> {
        self.out.flush()?;
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_and_record_bytes() {
        let mut w = PcapWriter::new(Vec::new()).unwrap();
        w.frame(1_500_002, &[0xAA, 0xBB]).unwrap();
        let bytes = w.finish().unwrap();
        assert_eq!(
            bytes,
            vec![
                0xD4, 0xC3, 0xB2, 0xA1, 2, 0, 4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xFF, 0xFF, 0, 0, 1, 0,
                0, 0, 1, 0, 0, 0, 0x22, 0xA1, 0x07, 0, 2, 0, 0, 0, 2, 0, 0, 0, 0xAA, 0xBB,
            ]
        );
    }
}
