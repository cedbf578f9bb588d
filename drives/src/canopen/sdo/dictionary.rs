//! The object dictionary as the SDO server sees it (CiA 301 §7.4): entries addressed by
//! index and sub-index, each with an access right and a size, read and written as bytes
//! (little-endian, as they travel). The simulator's CANopen node implements it over its
//! objects; the server never needs more.

use super::abort::AbortCode;
use super::command::Multiplexer;

/// Access right of an entry (CiA 306 `AccessType`: ro, wo, rw, const).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// Read only (may change, e.g. a status).
    ReadOnly,
    /// Write only.
    WriteOnly,
    /// Read and write.
    ReadWrite,
    /// Constant: read only, never changes.
    Const,
}

impl Access {
    /// Whether an SDO upload may read it.
    pub const fn readable(self) -> bool {
        !matches!(self, Self::WriteOnly)
    }

    /// Whether an SDO download may write it.
    pub const fn writable(self) -> bool {
        matches!(self, Self::WriteOnly | Self::ReadWrite)
    }
}

/// The size of an entry's value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ObjectSize {
    /// A basic type of this many bytes: a download of another length is refused with
    /// 0x06070012 (too high) or 0x06070013 (too low).
    Fixed(usize),
    /// VISIBLE_STRING, OCTET_STRING, DOMAIN: any length up to `max`.
    Variable {
        /// Largest length accepted.
        max: usize,
    },
}

impl ObjectSize {
    /// Checks a download's length against it (CiA 301 Table 22, 0x0607_00xx).
    pub const fn check(self, len: usize) -> Result<(), AbortCode> {
        match self {
            Self::Fixed(n) if len > n => Err(AbortCode::LENGTH_TOO_HIGH),
            Self::Fixed(n) if len < n => Err(AbortCode::LENGTH_TOO_LOW),
            Self::Variable { max } if len > max => Err(AbortCode::LENGTH_TOO_HIGH),
            _ => Ok(()),
        }
    }
}

/// What the server needs to know of an entry before a transfer starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EntryInfo {
    /// Access right.
    pub access: Access,
    /// Value size.
    pub size: ObjectSize,
}

/// An object dictionary served over SDO. Errors are the abort code the server sends.
pub trait ObjectDictionary {
    /// The entry at `mux`: 0x06020000 if the index does not exist, 0x06090011 if the
    /// sub-index does not.
    fn entry(&self, mux: Multiplexer) -> Result<EntryInfo, AbortCode>;

    /// Copies the value into `out` and returns its length (0x05040005 if `out` is too
    /// small). Called only for readable entries.
    fn read(&mut self, mux: Multiplexer, out: &mut [u8]) -> Result<usize, AbortCode>;

    /// Writes the whole value (length already checked against [`EntryInfo::size`]); the
    /// dictionary may still refuse the value (0x0609003x) or the state (0x08000022).
    fn write(&mut self, mux: Multiplexer, data: &[u8]) -> Result<(), AbortCode>;
}

#[cfg(test)]
pub(crate) mod test_dictionary {
    //! A dictionary for tests: a list of entries with their bytes.
    use super::*;

    /// One entry.
    pub struct TestEntry {
        pub mux: Multiplexer,
        pub access: Access,
        pub size: ObjectSize,
        pub value: Vec<u8>,
    }

    /// Entries in a vector; writes are recorded.
    #[derive(Default)]
    pub struct TestDictionary {
        pub entries: Vec<TestEntry>,
        pub writes: usize,
    }

    impl TestDictionary {
        pub fn with(
            mut self,
            index: u16,
            sub: u8,
            access: Access,
            size: ObjectSize,
            value: &[u8],
        ) -> Self {
            self.entries.push(TestEntry {
                mux: Multiplexer::new(index, sub),
                access,
                size,
                value: value.to_vec(),
            });
            self
        }

        pub fn value(&self, index: u16, sub: u8) -> &[u8] {
            &self
                .entries
                .iter()
                .find(|e| e.mux == Multiplexer::new(index, sub))
                .unwrap()
                .value
        }
    }

    impl ObjectDictionary for TestDictionary {
        fn entry(&self, mux: Multiplexer) -> Result<EntryInfo, AbortCode> {
            match self.entries.iter().find(|e| e.mux == mux) {
                Some(e) => Ok(EntryInfo {
                    access: e.access,
                    size: e.size,
                }),
                None if self.entries.iter().any(|e| e.mux.index == mux.index) => {
                    Err(AbortCode::SUB_INDEX_DOES_NOT_EXIST)
                }
                None => Err(AbortCode::OBJECT_DOES_NOT_EXIST),
            }
        }

        fn read(&mut self, mux: Multiplexer, out: &mut [u8]) -> Result<usize, AbortCode> {
            let e = self
                .entries
                .iter()
                .find(|e| e.mux == mux)
                .ok_or(AbortCode::OBJECT_DOES_NOT_EXIST)?;
            let dst = out
                .get_mut(..e.value.len())
                .ok_or(AbortCode::OUT_OF_MEMORY)?;
            dst.copy_from_slice(&e.value);
            Ok(e.value.len())
        }

        fn write(&mut self, mux: Multiplexer, data: &[u8]) -> Result<(), AbortCode> {
            let e = self
                .entries
                .iter_mut()
                .find(|e| e.mux == mux)
                .ok_or(AbortCode::OBJECT_DOES_NOT_EXIST)?;
            e.value = data.to_vec();
            self.writes += 1;
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn access_rights() {
        assert!(Access::ReadOnly.readable() && !Access::ReadOnly.writable());
        assert!(Access::Const.readable() && !Access::Const.writable());
        assert!(!Access::WriteOnly.readable() && Access::WriteOnly.writable());
        assert!(Access::ReadWrite.readable() && Access::ReadWrite.writable());
    }

    #[test]
    fn size_checks_name_too_high_and_too_low() {
        assert_eq!(ObjectSize::Fixed(4).check(4), Ok(()));
        assert_eq!(
            ObjectSize::Fixed(4).check(5),
            Err(AbortCode::LENGTH_TOO_HIGH)
        );
        assert_eq!(
            ObjectSize::Fixed(4).check(2),
            Err(AbortCode::LENGTH_TOO_LOW)
        );
        assert_eq!(ObjectSize::Variable { max: 10 }.check(0), Ok(()));
        assert_eq!(
            ObjectSize::Variable { max: 10 }.check(11),
            Err(AbortCode::LENGTH_TOO_HIGH)
        );
    }
}
