//! SYNC (CiA 301 §7.2.5): the producer's periodic trigger on 0x080 on which synchronous
//! PDOs are sent and acted on. Zero data bytes, or one byte counter 1..=240 when object
//! 0x1019 (synchronous counter overflow value) is 2..=240.

use super::cob_id::SYNC_COB_ID;
use super::frame::CanFrame;
use thiserror::Error;

/// Largest counter overflow value of 0x1019 (object 0x1019, CiA 301 §7.5.2).
pub const MAX_COUNTER: u8 = 240;

/// Why a frame is not a SYNC.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum SyncError {
    /// Not COB-ID 0x080.
    #[error("SYNC: COB-ID 0x{0:03X}, expected 0x080")]
    CobId(u16),
    /// A remote frame.
    #[error("SYNC: remote frame, CiA 301 §7.2.5 uses a data frame")]
    Remote,
    /// Neither 0 nor 1 data bytes.
    #[error("SYNC: {0} data bytes, expected 0 or 1 (counter)")]
    Length(usize),
    /// A counter outside 1..=240.
    #[error("SYNC: byte 0 counter {0} is outside 1..=240 (CiA 301 §7.2.5.2.1)")]
    Counter(u8),
}

/// A SYNC, with its counter when the producer sends one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Sync {
    counter: Option<u8>,
}

impl Sync {
    /// A SYNC without counter.
    pub const fn new() -> Self {
        Self { counter: None }
    }

    /// A SYNC with counter 1..=240.
    pub const fn with_counter(counter: u8) -> Result<Self, SyncError> {
        if counter >= 1 && counter <= MAX_COUNTER {
            Ok(Self {
                counter: Some(counter),
            })
        } else {
            Err(SyncError::Counter(counter))
        }
    }

    /// The counter, if any.
    pub const fn counter(&self) -> Option<u8> {
        self.counter
    }

    /// The counter that follows `counter` when 0x1019 is `overflow` (2..=240): counting
    /// restarts at 1 after `overflow` (CiA 301 §7.2.5.2.1). None if `overflow` is not a
    /// counter overflow value.
    pub const fn next_counter(counter: u8, overflow: u8) -> Option<u8> {
        if overflow < 2 || overflow > MAX_COUNTER {
            return None;
        }
        Some(if counter >= overflow { 1 } else { counter + 1 })
    }

    /// Parses a received frame.
    pub fn parse(frame: &CanFrame) -> Result<Self, SyncError> {
        if frame.id() != SYNC_COB_ID {
            return Err(SyncError::CobId(frame.id()));
        }
        if frame.is_remote() {
            return Err(SyncError::Remote);
        }
        match frame.data() {
            [] => Ok(Self::new()),
            &[c] => Self::with_counter(c),
            d => Err(SyncError::Length(d.len())),
        }
    }

    /// The frame to send.
    pub fn emit(&self) -> CanFrame {
        match self.counter {
            None => CanFrame::from_parts_len(SYNC_COB_ID, [0; 8], 0),
            Some(c) => CanFrame::from_parts_len(SYNC_COB_ID, [c, 0, 0, 0, 0, 0, 0, 0], 1),
        }
    }
}

impl Default for Sync {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn fixtures_parse_and_emit() {
        // CiA 301 §7.2.5.3.1: 0x080 with no data, or with the counter byte.
        let plain = CanFrame::new(0x080, &[]).unwrap();
        assert_eq!(Sync::parse(&plain), Ok(Sync::new()));
        assert_eq!(Sync::new().emit(), plain);
        for c in [1u8, 17, 240] {
            let frame = CanFrame::new(0x080, &[c]).unwrap();
            let s = Sync::parse(&frame).unwrap();
            assert_eq!(s.counter(), Some(c));
            assert_eq!(s.emit(), frame);
        }
    }

    #[test]
    fn refuses_bad_frames_naming_the_field() {
        let p = |id, d: &[u8]| Sync::parse(&CanFrame::new(id, d).unwrap());
        assert_eq!(p(0x081, &[]), Err(SyncError::CobId(0x81)));
        assert_eq!(p(0x080, &[0]), Err(SyncError::Counter(0)));
        assert_eq!(p(0x080, &[241]), Err(SyncError::Counter(241)));
        assert_eq!(p(0x080, &[1, 2]), Err(SyncError::Length(2)));
        assert_eq!(
            Sync::parse(&CanFrame::new_remote(0x80, 0).unwrap()),
            Err(SyncError::Remote)
        );
    }

    #[test]
    fn counter_wraps_to_1_after_overflow_value() {
        assert_eq!(Sync::next_counter(1, 3), Some(2));
        assert_eq!(Sync::next_counter(3, 3), Some(1));
        assert_eq!(Sync::next_counter(240, 240), Some(1));
        assert_eq!(Sync::next_counter(1, 1), None);
        assert_eq!(Sync::next_counter(1, 241), None);
    }

    proptest! {
        #[test]
        fn any_frame_parses_or_errs_and_round_trips(id in 0u32..0x800, data in proptest::collection::vec(any::<u8>(), 0..=8)) {
            let frame = CanFrame::new(id, &data).unwrap();
            if let Ok(p) = Sync::parse(&frame) {
                prop_assert_eq!(p.emit(), frame);
            }
        }
    }
}
