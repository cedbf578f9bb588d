//! The cyclic frame with 1 simulated servo(s): the mapped bytes in one LRW datagram plus
//! one fixed-size datagram in the same frame (the FRMW of the DC time, or one cycle in
//! `AL_STATUS_EVERY` the BRD of AL status in its place), no datagram per slave; a slave
//! pulled mid-run is seen by the working counter in that cycle and named in the next.
//! See `gantry_tests::cyclic_frame`.

#[test]
fn the_cyclic_frame_is_the_mapped_bytes_plus_one_fixed_datagram_with_1_slaves() {
    let f = gantry_tests::cyclic_frame::steady_frame_and_a_pulled_slave(1, true);
    eprintln!("{f:?}");
}
