//! The cyclic frame with 1 simulated servo(s): the mapped bytes in one LRW datagram plus
//! two fixed ones in the same frame (BRD of AL status, FRMW of the DC time), no datagram per slave; a slave pulled mid-run is named in the
//! next cycle. See `gantry_tests::cyclic_frame`.

#[test]
fn the_cyclic_frame_is_the_mapped_bytes_plus_fixed_datagrams_with_1_slaves() {
    let f = gantry_tests::cyclic_frame::steady_frame_and_a_pulled_slave(1);
    eprintln!("{f:?}");
}
