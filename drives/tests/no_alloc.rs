//! The master's per-drive cycle work allocates nothing: a counting global allocator
//! watches this thread while a linear and a modulo channel decode their inputs through
//! the process-data view, give feedback, step the power state machine, count targets
//! across the 32-bit wrap and encode their outputs, for 20 000 cycles.

use gantry_drives::cia402::image::{InputImage, OutputImage};
use gantry_drives::cia402::pdo::PdoLayout;
use gantry_drives::cia402::{Controlword, Statusword};
use gantry_drives::csp::{encode_outputs, CspChannel, CspSetpoint};
use gantry_drives::scaling::{Scaling, ScalingConfig};

mod counting {
    include!("../../kernel/tests/common/counting_alloc.rs");
}

#[global_allocator]
static ALLOC: counting::Counting = counting::Counting;

#[test]
fn the_cycle_path_of_a_channel_does_not_allocate() {
    let scaling = Scaling::new(ScalingConfig {
        counts_per_motor_rev: 1 << 20,
        motor_revs: 7,
        load_revs: 3,
        units_per_load_rev: 360.0,
        invert: false,
    })
    .unwrap();
    let layout = PdoLayout::csp();
    let mut channels = [
        CspChannel::with_layout(scaling, &layout).unwrap(),
        CspChannel::with_layout(scaling, &layout).unwrap(),
    ];
    channels[1].set_modulo_period(Some(360.0)).unwrap();
    let map = *channels[0].offsets.map();
    // The drives: enabled, each at the target it was sent last cycle.
    let mut drive_inputs = [[0u8; 15]; 2];
    let mut outputs = [[0u8; 7]; 2];
    let mut sent = [i32::MAX - 1000, 5];
    // Set positions (units, unwrapped): each axis moves 0.5° a cycle (3398 counts).
    let mut set = [f64::NAN; 2];
    counting::watch(true);
    for cycle in 0..20_000u32 {
        for (i, ch) in channels.iter_mut().enumerate() {
            // The drive's side: the position it was sent, Operation enabled.
            let mut img = InputImage::new_checked(&mut drive_inputs[i][..], &map).unwrap();
            img.set_statusword(Statusword(0x0637));
            img.set_position_actual_value(sent[i]);
            img.set_velocity_actual_value(1000);
            // The master's side.
            let inputs = ch.decode(&drive_inputs[i]).unwrap();
            let fb = ch.drive_feedback(&inputs);
            // Taken over where the drive stands, then on by 0.5° a cycle; the modulo
            // axis' set value as whole periods and the position within.
            set[i] = if cycle == 0 {
                fb.position
            } else {
                set[i] + 0.5
            };
            let turns = if i == 1 {
                (set[i] / 360.0).floor()
            } else {
                0.0
            };
            let sp = CspSetpoint {
                position: set[i] - turns * 360.0,
                turns: turns as i64,
                enable: true,
                reset_fault: false,
                probe: Default::default(),
            };
            let (cw, target) = ch.drive_outputs(&sp, &inputs);
            encode_outputs(&ch.offsets, &mut outputs[i], cw, target);
            let out = OutputImage::new_checked(&outputs[i][..], &map).unwrap();
            assert_eq!(out.controlword(), Some(Controlword(0x0F)));
            sent[i] = out.target_position().unwrap();
        }
    }
    counting::watch(false);
    assert_eq!(counting::take_count(), 0, "allocations on the cycle path");
    // The linear drive went past 2³¹ counts (its counter wrapped, the channel did not),
    // and both travelled to the count: the last actual is the target of the cycle before
    // the last, 19 998 · 0.5° from the first.
    let per_degree = f64::from(1u32 << 20) * 7.0 / 3.0 / 360.0;
    let travel = (19_998.0 * 0.5 * per_degree).round() as i64;
    assert!(channels[0].actual_counts() > i64::from(i32::MAX));
    for (ch, start) in channels.iter().zip([i32::MAX - 1000, 5]) {
        let moved = ch.actual_counts() - i64::from(start);
        assert!(
            (moved - travel).abs() <= 1,
            "{moved} counts, {travel} expected"
        );
    }
}
