//! The axis. STUB: being written.
/// Kind of axis.
#[derive(Clone, Copy, Debug)]
pub enum AxisKind {
    /** simulated */
    Simulated,
}
/// Axis configuration.
#[derive(Clone, Debug)]
pub struct AxisConfig;
/// An axis.
#[derive(Clone, Debug)]
pub struct Axis;
