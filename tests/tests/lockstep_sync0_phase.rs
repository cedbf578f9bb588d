//! What the phase lock is for, judged by the drive, in lockstep (injected time, no host
//! jitter). A DC drive takes its setpoint at its own SYNC0 edge: a frame that lands after
//! the edge it was meant for leaves that edge without a setpoint (missed); two frames
//! between two edges give it two, the first never taken (doubled). The drive's clock runs
//! 500 ppm off the master's (a poor quartz; the first DC slave is the reference, so SYNC0
//! follows it). Free-running, the master's 1 ms cycle walks 0.5 µs a cycle through the
//! SYNC0 period and, within 2400 cycles (1.2 periods), crosses an edge: the drive counts a
//! missed setpoint where its clock is fast, a doubled one where it is slow. Phase-locked
//! ([`PhaseLock`], what `gantry run` does with DC: the next deadline moves by the lock's
//! correction after each frame), the frames stay a quarter period after SYNC0 and the
//! drive counts nothing.

use std::time::Duration;

use ethercrab::std::ethercat_now;
use ethercrab::subdevice_group::DcConfiguration;
use ethercrab::{DcSync, MainDevice, MainDeviceConfig, PduStorage};
use gantry::ethercat::transition;
use gantry::runtime::phase::PhaseLock;
use gantry_sim::catalog::{self, ServoOptions};
use gantry_sim::chain::SlaveChain;
use gantry_sim::plant::record::DriveRecord;
use gantry_tests::lockstep::Lockstep;

const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_FAST: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();
static PDU_SLOW: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

const PERIOD_NS: u64 = 1_000_000;
const DRIFT_PPM: f64 = 500.0;

/// What the drive counted: (locked, free-running) differences of its record, and its AL
/// status after the locked cycles.
struct Counts {
    locked: (u32, u32),
    free: (u32, u32),
    al_after_locked: u16,
}

fn record(net: &Lockstep) -> DriveRecord {
    *net.chain.slaves()[0].device().record().expect("a drive")
}

fn run(storage: &'static PduStorage<16, MAX_PDU_DATA>, drift_ppm: f64) -> Counts {
    let (tx, rx, pdu_loop) = storage.try_split().expect("split once");
    let chain = SlaveChain::new(vec![
        catalog::servo(ServoOptions::default()).with_dc_drift_ppm(drift_ppm)
    ]);
    let mut net = Lockstep::new(tx, rx, chain);
    let md = MainDevice::new(
        pdu_loop,
        gantry_tests::lockstep_timeouts(),
        MainDeviceConfig::default(),
    );
    let mut group = net
        .block_on(md.init_single_group::<2, 64>(ethercat_now))
        .unwrap();
    for mut sd in group.iter_mut(&md) {
        sd.set_dc_sync(DcSync::Sync0);
    }
    let group = net.block_on(group.into_pre_op_pdi(&md)).unwrap();
    let group = net
        .block_on(group.configure_dc_sync(
            &md,
            DcConfiguration {
                start_delay: Duration::from_millis(10),
                sync0_period: Duration::from_nanos(PERIOD_NS),
                sync0_shift: Duration::ZERO,
            },
        ))
        .unwrap();
    let group = net
        .block_on(async {
            transition::into_op(group.into_safe_op(&md).await?, &md, transition::OP_TIMEOUT).await
        })
        .unwrap();
    assert_eq!(net.chain.slaves()[0].al_status(), 0x08);

    // The master's cycle: it starts every PERIOD_NS of its own (the chain's) time, moved by
    // the lock's correction when locked; its frame goes out at the start.
    let lock = PhaseLock::new(PERIOD_NS);
    let mut next = net.chain.now_ns();
    let mut cycles = |net: &mut Lockstep, n: usize, locked: bool| {
        for _ in 0..n {
            let now = net.chain.now_ns();
            net.chain.advance(next.saturating_sub(now));
            let response = net.block_on(group.tx_rx_dc(&md)).unwrap();
            let offset = response.extra.cycle_start_offset.as_nanos() as u64;
            let correction = if locked {
                lock.correction_ns(offset)
            } else {
                0
            };
            next = next.saturating_add_signed(PERIOD_NS as i64 + correction);
        }
    };
    // Locked: 200 cycles to pull in (a crossing on the way costs at most one setpoint,
    // which the drive tolerates), then 3000 cycles, 1.5 periods' worth of drift.
    cycles(&mut net, 200, true);
    let before = record(&net);
    cycles(&mut net, 3000, true);
    let locked = record(&net);
    let al_after_locked = net.chain.slaves()[0].al_status();
    cycles(&mut net, 2400, false);
    let free = record(&net);
    Counts {
        locked: (
            locked.sync_missed - before.sync_missed,
            locked.sync_doubled - before.sync_doubled,
        ),
        free: (
            free.sync_missed - locked.sync_missed,
            free.sync_doubled - locked.sync_doubled,
        ),
        al_after_locked,
    }
}

#[test]
fn a_fast_drive_misses_setpoints_only_when_the_cycle_is_not_locked() {
    let c = run(&PDU_FAST, DRIFT_PPM);
    eprintln!(
        "+{DRIFT_PPM} ppm: locked (missed, doubled) {:?}, free-running {:?}",
        c.locked, c.free
    );
    assert_eq!(c.al_after_locked, 0x08, "in Op through the locked cycles");
    assert_eq!(c.locked, (0, 0), "locked: one setpoint at every SYNC0");
    assert!(c.free.0 >= 1, "free-running: the edges overtake the frames");
}

#[test]
fn a_slow_drive_gets_doubled_setpoints_only_when_the_cycle_is_not_locked() {
    let c = run(&PDU_SLOW, -DRIFT_PPM);
    eprintln!(
        "-{DRIFT_PPM} ppm: locked (missed, doubled) {:?}, free-running {:?}",
        c.locked, c.free
    );
    assert_eq!(c.al_after_locked, 0x08, "in Op through the locked cycles");
    assert_eq!(c.locked, (0, 0), "locked: one setpoint at every SYNC0");
    assert!(c.free.1 >= 1, "free-running: the frames overtake the edges");
}
