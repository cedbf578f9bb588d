//! EtherCAT costs per cycle with 16 CiA-402 servos, in one thread (no hand-offs):
//! - the simulator serving the 16-drive LRW frame (per frame; the README divides by 16);
//! - the master's whole cycle: decode 16 drives, kernel step, encode, ethercrab builds the
//!   frame and parses the reply — measured with the simulator inside it, so the master's
//!   share is this minus the simulator's line;
//! - the kernel step for 16 axes alone, the baseline of the same run;
//! - the cyclic frame gantry sends (the LRW of the mapped bytes alone) beside ethercrab's
//!   `tx_rx` (the LRW and one AL-status FPRD per slave);
//!
//! and prints, before the timings, the bytes per cycle on the wire and their time at
//! 100 Mbit/s for 1, 16 and 64 servos: gantry's frame, ethercrab's `tx_rx`/`tx_rx_dc`
//! frames, and the minimum (the mapped bytes with the Ethernet, EtherCAT and datagram
//! headers). The 16-servo figures of both frames are the frames this bench captured; the
//! others follow from the same packing (checked against the captured ones).

use std::cell::RefCell;

use ethercrab::std::ethercat_now;
use ethercrab::subdevice_group::Op;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, SubDeviceGroup};
use gantry::ethercat::bus::MAX_DATAGRAM;
use gantry::ethercat::frame::{self, datagram_bytes, wire_bytes, wire_us, ProcessImage};
use gantry::ethercat::transition;
use gantry::runtime::cycle::Cycle;
use gantry_drives::csp::CspChannel;
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
    cycle: Cycle,
    image: ProcessImage,
}

/// Datagram bytes one frame of ethercrab's holds (its PDU buffer: the storage element
/// less the Ethernet and EtherCAT headers).
const fn frame_capacity(max_datagram: usize) -> usize {
    max_datagram + frame::DATAGRAM_HEADER + frame::WORKING_COUNTER
}

/// Bytes on the wire of ethercrab 0.7.1's `tx_rx` (`dc`: `tx_rx_dc`) for `slaves` slaves
/// and `pdi` bytes of process data, frames of `capacity` datagram bytes: its packing
/// (`SubDeviceGroup::tx_rx`): per frame, the FRMW first (DC, first frame only), as much
/// of the image as fits in one LRW, then as many AL-status FPRDs (2 bytes each) as fit.
fn ethercrab_wire_bytes(slaves: usize, pdi: usize, capacity: usize, dc: bool) -> usize {
    let (mut pdi_left, mut checks_left, mut first, mut total) = (pdi, slaves, true, 0);
    while pdi_left > 0 || checks_left > 0 || first {
        let mut used = 0;
        if first && dc {
            used += datagram_bytes(frame::DC_TIME_BYTES);
        }
        first = false;
        if pdi_left > 0 {
            let take = pdi_left.min(capacity - used - datagram_bytes(0));
            pdi_left -= take;
            used += datagram_bytes(take);
        }
        while checks_left > 0 && used + datagram_bytes(2) <= capacity {
            checks_left -= 1;
            used += datagram_bytes(2);
        }
        total += wire_bytes(used);
    }
    total
}

/// The table of bytes per cycle; `per_servo` is one servo's (inputs, outputs).
fn print_frame_table(per_servo: (usize, usize)) {
    let capacity = frame_capacity(MAX_DATAGRAM);
    let cell = |bytes: usize| format!("{bytes:>5} B {:>6.1} µs", wire_us(bytes));
    let frmw = datagram_bytes(frame::DC_TIME_BYTES);
    println!(
        "bytes per cycle on the wire at 100 Mbit/s (preamble, gap, FCS, padding counted)\n\
         {:>6} {:>7} | {:^16} | {:^16} | {:^16} | {:^16} | {:^16}",
        "slaves", "mapped", "minimum", "gantry", "gantry + DC", "tx_rx", "tx_rx_dc"
    );
    for n in [1usize, 16, 64] {
        let image = ProcessImage::new(&vec![per_servo; n], MAX_DATAGRAM).unwrap();
        // A steady cycle: the LRW alone, with DC the FRMW beside it (one cycle in
        // `AL_STATUS_EVERY` sends the 14-byte AL-status BRD, in the FRMW's place).
        println!(
            "{n:>6} {:>5} B | {} | {} | {} | {} | {}",
            image.len(),
            cell(image.minimum_wire_bytes()),
            cell(image.wire_bytes(0)),
            cell(image.wire_bytes(frmw)),
            cell(ethercrab_wire_bytes(n, image.len(), capacity, false)),
            cell(ethercrab_wire_bytes(n, image.len(), capacity, true)),
        );
    }
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
    let mut cycle = Cycle::new(kernel(), vec![CspChannel::new(ball_screw_5mm()); DRIVES]);
    for i in 0..DRIVES {
        cycle
            .kernel
            .command(i, Command::Power(PowerCommand::Enable))
            .unwrap();
    }
    let image = ProcessImage::of_group(&group, &md, MAX_PDU_DATA - PduStorage::element_size(0))
        .expect("ethercrab's image as gantry lays it out");
    let mut b = Bench {
        md,
        group,
        net,
        cycle,
        image,
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
    // The frames as sent: gantry's, and ethercrab's tx_rx (both checked against the
    // figures the table computes).
    let capacity = frame_capacity(MAX_PDU_DATA - PduStorage::element_size(0));
    let sent = |b: &Bench| wire_bytes(b.net.last_sent.len() - 16);
    lrw_cycle(&mut b);
    assert_eq!(
        sent(&b),
        b.image.wire_bytes(0),
        "gantry's frame as captured"
    );
    one_cycle(&mut b);
    assert_eq!(
        sent(&b),
        ethercrab_wire_bytes(DRIVES, b.image.len(), capacity, false),
        "ethercrab's tx_rx frame as captured"
    );
    let per_servo = {
        let sd = b.group.subdevice(&b.md, 0).unwrap();
        let sizes = (sd.inputs_raw().len(), sd.outputs_raw().len());
        sizes
    };
    print_frame_table(per_servo);
    b
}

/// gantry's cycle: the image's LRW (what `EthercatBus` sends in a steady cycle without
/// DC; the bench's lockstep pump sends frames as queued).
fn lrw_cycle(b: &mut Bench) {
    for i in 0..DRIVES {
        b.cycle.read_inputs(i, b.image.inputs(i)).unwrap();
    }
    b.cycle.step();
    for i in 0..DRIVES {
        b.cycle.write_outputs(i, b.image.outputs_mut(i)).unwrap();
    }
    let r = b.net.block_on(b.image.exchange(&b.md)).unwrap();
    assert_eq!(r.working_counter, 3 * DRIVES as u16);
    b.net.chain.tick(1e-3);
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

/// Master: one whole cycle of 16 drives with ethercrab's `tx_rx` (LRW + 16 FPRDs), the
/// simulator's serving included.
#[divan::bench]
fn master_cycle_16_drives_with_sim(bencher: divan::Bencher) {
    with_bench(|b| bencher.bench_local(|| one_cycle(b)));
}

/// Master: one whole cycle of 16 drives with gantry's frame (the LRW alone), the
/// simulator's serving included.
#[divan::bench]
fn master_cycle_16_drives_lrw_alone_with_sim(bencher: divan::Bencher) {
    with_bench(|b| bencher.bench_local(|| lrw_cycle(b)));
}

/// Baseline: the kernel step for 16 moving axes alone (on the last feedback).
#[divan::bench]
fn kernel_step_16_axes(bencher: divan::Bencher) {
    with_bench(|b| bencher.bench_local(|| b.cycle.step()));
}
