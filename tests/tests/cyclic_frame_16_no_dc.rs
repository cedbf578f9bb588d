//! The cyclic frame with 16 simulated servos and no distributed clocks: the mapped bytes
//! in one LRW datagram alone — the minimum — but one cycle in `AL_STATUS_EVERY` that adds
//! the BRD of AL status; a slave pulled mid-run is seen by the working counter in that
//! cycle and named in the next. See `gantry_tests::cyclic_frame`.

#[test]
fn without_dc_the_cyclic_frame_is_the_mapped_bytes_alone_with_16_slaves() {
    let f = gantry_tests::cyclic_frame::steady_frame_and_a_pulled_slave(16, false);
    eprintln!("{f:?}");
}
