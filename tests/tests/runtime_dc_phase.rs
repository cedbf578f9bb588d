//! The cycle follows the reference clock (see `gantry_tests::dc_phase`), on an ordinary
//! thread: the phase lock locks on and holds whatever this host's timing. How many single
//! frames land within 100 µs of the target depends on the thread's wake-ups; the
//! real-time figure (the README's) is `runtime_dc_phase_rt.rs`. Measured on the shared
//! 2-vCPU VM under other builds, 29 runs: 74–100 %, median 98 % — reported, not asserted.

#[test]
fn the_cycle_holds_its_phase_to_a_drifting_reference_clock() {
    gantry_tests::dc_phase::run().check_lock();
}
