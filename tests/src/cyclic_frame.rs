//! The cyclic frame as it goes on the wire, read back from the bus' pcap capture: the
//! scenario behind the README's bytes-per-cycle figures, run by one test file per slave
//! count (one bus per process).
//!
//! On the wire (ETG.1000.4 §5.3, §5.4): Ethernet header (14 B), EtherCAT header (2 B: length
//! in bits 0..11), then datagrams of command (1), index (1), address (4), length (2: bits
//! 0..11, bit 15 "more datagrams follow"), IRQ (2), data, working counter (2).

use gantry::ethercat::frame::{self, datagram_bytes, wire_bytes};
use gantry::ethercat::health::AL_STATUS_EVERY;
use gantry_kernel::axis::handle::CommandStatus;

use crate::invariant::{assert_drive_invariants, DriveUnderTest, TestConditions};
use crate::rig::Rig;

/// EtherCAT command codes (ETG.1000.4 Table 18).
pub const LRW: u8 = 12;
/// FPRD.
pub const FPRD: u8 = 4;
/// FRMW.
pub const FRMW: u8 = 14;
/// BRD.
pub const BRD: u8 = 7;

/// One datagram as captured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Datagram {
    /// Command code.
    pub command: u8,
    /// Data bytes.
    pub len: usize,
}

/// One frame the master sent: its length as captured (no FCS) and its datagrams.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SentFrame {
    /// Bytes captured (Ethernet header to the last working counter, or the padding).
    pub bytes: usize,
    /// Its datagrams.
    pub datagrams: Vec<Datagram>,
    /// A reply followed it in the capture (a lost frame has none).
    pub answered: bool,
}

impl SentFrame {
    /// Bytes on the wire: the frame, padded to the minimum, with FCS, preamble and gap.
    pub fn wire_bytes(&self) -> usize {
        let datagrams: usize = self.datagrams.iter().map(|d| datagram_bytes(d.len)).sum();
        wire_bytes(datagrams)
    }
}

/// The frames the master sent, from a pcap file (replies, whose source MAC has the
/// locally-administered bit the first slave sets, are left out).
pub fn sent_frames(pcap: &[u8]) -> Result<Vec<SentFrame>, String> {
    let mut at = 24;
    let mut frames: Vec<SentFrame> = Vec::new();
    while at + 16 <= pcap.len() {
        let caplen = u32::from_le_bytes(pcap[at + 8..at + 12].try_into().unwrap()) as usize;
        let data = pcap
            .get(at + 16..at + 16 + caplen)
            .ok_or_else(|| format!("pcap record at byte {at} cut short"))?;
        at += 16 + caplen;
        if data.len() < 16 || data[12..14] != [0x88, 0xA4] {
            continue;
        }
        if data[6] & 0x02 != 0 {
            if let Some(last) = frames.last_mut() {
                last.answered = true;
            }
            continue;
        }
        let ecat_len = usize::from(u16::from_le_bytes([data[14], data[15]]) & 0x07FF);
        let mut d = 16;
        let mut datagrams = Vec::new();
        while d + 10 <= 16 + ecat_len {
            let len_field = u16::from_le_bytes([data[d + 6], data[d + 7]]);
            let len = usize::from(len_field & 0x07FF);
            datagrams.push(Datagram {
                command: data[d],
                len,
            });
            d += datagram_bytes(len);
            if len_field & 0x8000 == 0 {
                break;
            }
        }
        frames.push(SentFrame {
            bytes: data.len(),
            datagrams,
            answered: false,
        });
    }
    Ok(frames)
}

/// What one slave count measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Figures {
    /// Slaves on the bus.
    pub slaves: usize,
    /// Process data bytes (the image).
    pub mapped: usize,
    /// Bytes on the wire per cycle in steady state (captured): LRW and FRMW.
    pub wire: usize,
    /// Bytes on the wire in the steady cycle that reads the AL-status summary (one in
    /// [`AL_STATUS_EVERY`]): LRW and BRD.
    pub summary_wire: usize,
    /// The least: the mapped bytes in LRW frames alone.
    pub minimum: usize,
    /// Steady cycles found in the capture.
    pub steady_cycles: usize,
}

/// Cycles the steady window runs (three summaries).
const STEADY: usize = 3 * AL_STATUS_EVERY as usize;

/// `slaves` simulated servos, with DC or without, two axes moving (the first and the last
/// drive): every steady cycle's frame is the LRW (the mapped bytes) and, with DC, the FRMW
/// of the DC time, but one in [`AL_STATUS_EVERY`] which carries the BRD of AL status (in
/// the FRMW's place); nothing per slave. Then the cable before the last slave is pulled: the working counter of that
/// very cycle shows it (no inputs of that reply reach the axes), the next cycle reads the
/// states and names it. Asserts the drive invariant over every drive; returns the figures.
pub fn steady_frame_and_a_pulled_slave(slaves: usize, dc: bool) -> Figures {
    let dir = std::env::temp_dir().join(format!("gantry-cyclic-frame-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let pcap = dir.join("bus.pcap");
    let mut config = crate::sim_config_strict(slaves, 1000);
    assert!(config.bus.dc, "DC is on by default");
    config.bus.dc = dc;
    config.bus.pcap = Some(pcap.display().to_string());
    let mut rig = Rig::new(&config);
    let last = slaves - 1;
    let axes: Vec<usize> = if last == 0 { vec![0] } else { vec![0, last] };
    for _ in 0..5000 {
        if !rig.engine.bus.health().is_starting() {
            break;
        }
        rig.run(1);
    }
    for axis in 0..slaves {
        assert_eq!(rig.bus_fault(axis), None, "axis {axis} after start");
        let drive = &rig.snapshot().drives[axis];
        assert_eq!(
            drive.error_code,
            Some(0),
            "axis {axis} after start: {drive:?}"
        );
    }
    for &axis in &axes {
        rig.enable_and_home(axis);
    }
    let moves: Vec<_> = axes.iter().map(|&a| rig.start_move(a, 5.0)).collect();
    let before = rig.engine.bus.frame_stats();
    rig.run(STEADY);
    let after = rig.engine.bus.frame_stats();
    assert_eq!(after.cycles - before.cycles, STEADY as u64);
    assert_eq!(
        after.state_reads, before.state_reads,
        "no slave's AL status read one by one while every slave is in OP"
    );
    assert_eq!(
        after.summaries - before.summaries,
        3,
        "the AL-status summary once in {AL_STATUS_EVERY} cycles"
    );
    let image_len = rig.engine.bus.image().len();
    let expected_wire = rig.engine.bus.cyclic_wire_bytes();
    let expected_summary_wire = rig.engine.bus.summary_wire_bytes();
    let minimum = rig.engine.bus.image().minimum_wire_bytes();
    let rig_chunks: Vec<usize> = rig
        .engine
        .bus
        .image()
        .chunks()
        .iter()
        .map(|c| c.bytes.len())
        .collect();
    for (h, &axis) in moves.iter().zip(&axes) {
        let status = rig.finish(h, 5000);
        let snap = rig.snapshot();
        assert_eq!(
            status,
            CommandStatus::Done,
            "axis {axis}: {:?}, drive {:?}, {} lost frames, {} overruns",
            snap.axes[axis].error,
            snap.drives[axis],
            rig.engine.bus.health().lost_total,
            snap.figures.overruns
        );
    }

    // The cable before the last slave is pulled. With one slave nothing answers at all:
    // the frame is lost, counted in that cycle. Else the working counter of that cycle
    // is short: no slave's inputs from that reply are taken (whose bytes are stale is not
    // known yet), and the next cycle reads the states and names it.
    let lost_before = rig.engine.bus.health().lost_total;
    let last_inputs = rig.engine.bus.image().inputs(last).to_vec();
    rig.chain.lock().unwrap().cut_before(Some(last));
    rig.run(1);
    if last == 0 {
        assert_eq!(rig.engine.bus.health().lost_total, lost_before + 1);
    } else {
        let health = &rig.engine.bus.health();
        assert!(
            (0..slaves).all(|i| !health.inputs_fresh(i)),
            "seen in the cycle it happened, by the working counter"
        );
        assert!(health.reads_states(), "the next cycle reads the states");
        assert_eq!(rig.bus_fault(last), None, "not named yet");
        rig.run(1);
        let address = 0x1000 + last;
        let named =
            format!("EtherCAT: slave {last} ({address:#06x}) does not answer (cable, power?)");
        assert_eq!(
            rig.bus_fault(last).as_deref(),
            Some(named.as_str()),
            "named the cycle after"
        );
        assert!(rig.bus_fault(0).is_none(), "the others go on");
        let health = &rig.engine.bus.health();
        assert!(health.inputs_fresh(0) && !health.inputs_fresh(last));
        assert_eq!(
            rig.engine.bus.image().inputs(last),
            last_inputs,
            "the lost slave's bytes are its last own inputs, not what ethercrab's image \
             held from its last read of the states"
        );
        assert_eq!(
            health.wkc_total, 0,
            "the slave that is gone explains its count"
        );
    }
    rig.run(5);
    rig.chain.lock().unwrap().cut_before(None);
    rig.run(5);
    {
        let chain = rig.chain.lock().unwrap();
        assert_drive_invariants(
            &chain,
            &DriveUnderTest::of_config(&config)
                .into_iter()
                .filter(|d| axes.contains(&d.slave))
                .collect::<Vec<_>>(),
            1e-3,
            TestConditions::default(),
        );
    }
    let Rig { engine, .. } = rig;
    engine.into_bus().shut_down(&mut std::io::sink());

    let bytes = std::fs::read(&pcap).expect("the capture");
    let frames = sent_frames(&bytes).expect("a readable capture");
    // The steady cycles as captured: the longest run of frames that are each one LRW of
    // the whole image and one fixed datagram — the FRMW of the DC time, or in one cycle in
    // AL_STATUS_EVERY the BRD of the AL status in its place (the exchange joins the
    // datagrams queued together into one frame; the image of up to 64 servos fits one).
    assert_eq!(rig_chunks, [image_len], "one LRW datagram");
    let lrw = Datagram {
        command: LRW,
        len: image_len,
    };
    let frmw = Datagram {
        command: FRMW,
        len: frame::DC_TIME_BYTES,
    };
    let brd = Datagram {
        command: BRD,
        len: frame::AL_STATUS_BYTES,
    };
    // In either order: the exchange takes them in the order of ethercrab's frame slots.
    let is = |f: &SentFrame, fixed: Option<Datagram>| {
        f.datagrams.len() == 1 + usize::from(fixed.is_some())
            && f.datagrams.contains(&lrw)
            && fixed.is_none_or(|d| f.datagrams.contains(&d))
    };
    let steady_fixed = dc.then_some(frmw);
    let (mut longest, mut run) = (0, 0);
    let (mut wire, mut summary_wire) = (None, None);
    let mut summaries_at = Vec::new();
    let mut longest_summaries = Vec::new();
    for f in &frames {
        // A frame nobody answered (the cable pulled with one slave) is no steady cycle.
        let (steady, summary) = (
            f.answered && is(f, steady_fixed),
            f.answered && is(f, Some(brd)),
        );
        if steady || summary {
            run += 1;
            let slot = if summary {
                summaries_at.push(run);
                &mut summary_wire
            } else {
                &mut wire
            };
            let bytes = f.wire_bytes();
            assert_eq!(
                *slot.get_or_insert(bytes),
                bytes,
                "every steady cycle alike"
            );
            if run > longest {
                longest = run;
                longest_summaries.clone_from(&summaries_at);
            }
        } else {
            (run, summaries_at) = (0, Vec::new());
        }
    }
    assert!(
        longest >= STEADY,
        "{longest} steady cycles in a row in the capture, {STEADY} run"
    );
    // The summaries AL_STATUS_EVERY cycles apart, no more.
    let every = AL_STATUS_EVERY as usize;
    assert!(longest_summaries.len() >= 3, "{longest_summaries:?}");
    assert!(
        longest_summaries.windows(2).all(|w| w[1] - w[0] == every),
        "{longest_summaries:?}"
    );
    let (wire, summary_wire) = (
        wire.expect("steady cycles"),
        summary_wire.expect("summary cycles"),
    );
    // No frame carries more than the LRW and one fixed datagram but those that read the
    // states one by one: at start, and after the cut.
    for f in &frames {
        let fprd = f.datagrams.iter().filter(|d| d.command == FPRD).count();
        if f.datagrams.contains(&lrw) && fprd == 0 {
            assert!(f.datagrams.len() <= 2, "{f:?}");
        }
    }
    assert!(frames
        .iter()
        .any(|f| f.datagrams.iter().filter(|d| d.command == FPRD).count() >= slaves));
    assert_eq!(wire, expected_wire);
    assert_eq!(summary_wire, expected_summary_wire);
    // The minimum's frame with one fixed datagram more with DC (20 bytes; the summary
    // cycle's BRD, 14), the minimum itself without, whatever the slave count; a single
    // slave's LRW frame is padded to the 64-byte minimum, so there they cost less.
    let fixed = if dc {
        datagram_bytes(frame::DC_TIME_BYTES)
    } else {
        0
    };
    assert_eq!(
        wire,
        wire_bytes(datagram_bytes(image_len) + fixed),
        "the mapped bytes + at most one fixed datagram"
    );
    if !dc {
        assert_eq!(wire, minimum, "without DC the LRW alone");
    }
    assert_eq!(
        summary_wire,
        wire_bytes(datagram_bytes(image_len) + datagram_bytes(frame::AL_STATUS_BYTES))
    );
    assert!(wire - minimum <= fixed);
    assert!(summary_wire - minimum <= datagram_bytes(frame::AL_STATUS_BYTES));
    Figures {
        slaves,
        mapped: image_len,
        wire,
        summary_wire,
        minimum,
        steady_cycles: longest,
    }
}
