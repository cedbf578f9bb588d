//! Two path segments joined in motion.

/// How a blended junction may leave the programmed path (PLCopen Part 4 TransitionMode;
/// Omron `_eMC_TRANSITION_MODE`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Transition {
    /// `_mcTMNone`: the path goes through the junction.
    #[default]
    None,
    /// `_mcTMCornerSuperimposed`: the next segment starts while the one before ends, so
    /// the corner is rounded.
    CornerSuperimposed,
}
