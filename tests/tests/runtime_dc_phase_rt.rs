//! README, "Distributed clocks": locked to a reference clock 300 ppm fast, ~98 % of the
//! frames reach it within 100 µs of the target — in the production configuration, a
//! SCHED_FIFO 80 cycle thread with locked memory and PM QoS, as `gantry run` makes it
//! (`rt::enter`). Measured on the shared, non-preemptible 2-vCPU VM, 13 runs: 96.2–99.8 %,
//! median 98.7 %, the misses matching the cycles the host woke over 100 µs late (printed).
//! The bound is 90 %.
//! Needs root (or CAP_SYS_NICE and CAP_IPC_LOCK); `deploy/test.sh` runs it.

#[test]
#[ignore = "needs SCHED_FIFO and mlockall (root); deploy/test.sh runs it"]
fn in_real_time_the_locked_frames_stay_within_100us_of_the_target() {
    let figures = std::thread::spawn(|| {
        let rt = gantry::config::RtSection {
            priority: 80,
            lock_memory: true,
            ..gantry::config::RtSection::default()
        };
        gantry::runtime::rt::enter(&rt).expect("real time (run as root)");
        gantry_tests::dc_phase::run()
    })
    .join()
    .expect("the cycle thread");
    figures.check_lock();
    assert!(
        figures.within_100us >= 900,
        "{} of 1000 frames within 100 µs of the target",
        figures.within_100us
    );
}
