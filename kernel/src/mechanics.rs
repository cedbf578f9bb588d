//! Mechanics and units. STUB: being written.
