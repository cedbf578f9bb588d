//! EtherCAT costs per cycle with 16 CiA-402 servos, in one thread (no hand-offs):
//! - the simulator serving the 16-drive LRW frame (per frame; the README divides by 16);
//! - the master's whole cycle: decode 16 drives, kernel step, encode, ethercrab builds the
//!   frame and parses the reply — measured with the simulator inside it, so the master's
//!   share is this minus the simulator's line;
//! - the kernel step for 16 axes alone, the baseline of the same run.

use std::cell::RefCell;

use ethercrab::std::ethercat_now;
use ethercrab::subdevice_group::Op;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, SubDeviceGroup};
use gantry::ethercat::cycle::CspCycle;
use gantry::ethercat::cyclic::CspChannel;
use gantry::ethercat::transition;
use gantry_kernel::axis::command::{Command, MovePtp, PositioningMode, PowerCommand};
use gantry_kernel::{AxisConfig, AxisKind, Kernel};
use gantry_tests::ball_screw_5mm;
use gantry_tests::lockstep::Lockstep;
use gantry_tests::servo_chain;

const DRIVES: usize = 16;
const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

type Group = SubDeviceGroup<DRIVES, 512, ethercrab::DefaultLock, Op>;

struct Bench {
    md: MainDevice<'static>,
    group: Group,
    net: Lockstep,
    cycle: CspCycle,
}

thread_local! {
    static BENCH: RefCell<Option<Bench>> = const { RefCell::new(None) };
}

fn kernel() -> Kernel {
    let axes = (0..DRIVES)
        .map(|i| AxisConfig::new(&format!("a{i}"), AxisKind::Real))
        .collect();
    Kernel::new(1e-3, axes).unwrap()
}

/// 16 servos in OP, enabled and moving (long moves, so they stay in motion).
fn setup() -> Bench {
    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().unwrap();
    let chain = servo_chain(DRIVES as u32);
    let mut net = Lockstep::new(tx, rx, chain);
    let md = MainDevice::new(
        pdu_loop,
        gantry_tests::lockstep_timeouts(),
        MainDeviceConfig::default(),
    );
    let group = net
        .block_on(md.init_single_group::<DRIVES, 512>(ethercat_now))
        .unwrap();
    let group = net
        .block_on(async {
            transition::into_op(group.into_safe_op(&md).await?, &md, transition::OP_TIMEOUT).await
        })
        .unwrap();
    let mut cycle = CspCycle::new(kernel(), vec![CspChannel::new(ball_screw_5mm()); DRIVES]);
    for i in 0..DRIVES {
        cycle
            .kernel
            .command(i, Command::Power(PowerCommand::Enable))
            .unwrap();
    }
    let mut b = Bench {
        md,
        group,
        net,
        cycle,
    };
    for _ in 0..50 {
        one_cycle(&mut b);
    }
    for i in 0..DRIVES {
        let long_move = MovePtp::new(PositioningMode::RelActual, 1e5);
        b.cycle
            .kernel
            .command(i, Command::MovePtp(long_move))
            .unwrap();
    }
    for _ in 0..200 {
        one_cycle(&mut b);
    }
    assert!(
        (0..DRIVES).all(|i| b.cycle.kernel.axis_status(i).unwrap().set.v > 0.0),
        "all drives move"
    );
    b
}

fn one_cycle(b: &mut Bench) {
    for i in 0..DRIVES {
        let sd = b.group.subdevice(&b.md, i).unwrap();
        b.cycle.read_inputs(i, &sd.inputs_raw()).unwrap();
    }
    b.cycle.step();
    for i in 0..DRIVES {
        let sd = b.group.subdevice(&b.md, i).unwrap();
        b.cycle.write_outputs(i, sd.io_raw_mut().outputs()).unwrap();
    }
    let r = b.net.block_on(b.group.tx_rx(&b.md)).unwrap();
    assert_eq!(r.working_counter, 3 * DRIVES as u16);
    b.net.chain.tick(1e-3);
}

fn with_bench<R>(f: impl FnOnce(&mut Bench) -> R) -> R {
    BENCH.with(|cell| {
        let mut cell = cell.borrow_mut();
        f(cell.get_or_insert_with(setup))
    })
}

fn main() {
    divan::main();
}

/// Simulator: the 16-drive LRW frame through the chain (per frame).
#[divan::bench]
fn sim_lrw_frame_16_drives(bencher: divan::Bencher) {
    with_bench(|b| {
        one_cycle(b);
        let frame = b.net.last_sent.clone();
        let chain = &mut b.net.chain;
        bencher
            .with_inputs(|| frame.clone())
            .bench_local_refs(|f| chain.process(f).unwrap());
    });
}

/// Master: one whole cycle of 16 drives, the simulator's serving included.
#[divan::bench]
fn master_cycle_16_drives_with_sim(bencher: divan::Bencher) {
    with_bench(|b| bencher.bench_local(|| one_cycle(b)));
}

/// Baseline: the kernel step for 16 moving axes alone (on the last feedback).
#[divan::bench]
fn kernel_step_16_axes(bencher: divan::Bencher) {
    with_bench(|b| bencher.bench_local(|| b.cycle.step()));
}
