//! The kernel. STUB: being written.
/// The kernel.
pub struct Kernel;
