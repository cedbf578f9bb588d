//! The real-time side: the cycle clock and the figures every cycle records. (The RT
//! thread itself, with priority, affinity and memory locking, is issue 4.)

pub mod clock;
pub mod histogram;
