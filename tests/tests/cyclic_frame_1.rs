//! The cyclic frame with 1 simulated servo(s): the mapped bytes in one LRW datagram plus
//! one fixed FRMW datagram (DC) in the same frame, no datagram per slave; a slave pulled mid-run is named in the
//! next cycle. See `gantry_tests::cyclic_frame`.

#[test]
fn the_cyclic_frame_is_the_mapped_bytes_plus_one_fixed_datagram_with_1_slaves() {
    let f = gantry_tests::cyclic_frame::steady_frame_and_a_pulled_slave(1);
    eprintln!("{f:?}");
}
