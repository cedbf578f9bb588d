//! An independent master — ethercrab, which no one here wrote — scans the simulated slave
//! chain in the same process: it counts the slaves, gives them addresses, reads their
//! identity and names from the emulated EEPROM, and walks them through the AL states. The
//! frames go from ethercrab's PDU loop straight into `SlaveChain::process` and back.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::task::{Wake, Waker};
use std::thread::Thread;
use std::time::Duration;

use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, Timeouts};
use gantry_sim::chain::SlaveChain;
use gantry_sim::esc::sii::DeviceDescription;
use gantry_sim::slave::Slave;

const MAX_SUBDEVICES: usize = 8;
const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
const MAX_FRAMES: usize = 16;
const PDI_LEN: usize = 64;

static PDU_STORAGE: PduStorage<MAX_FRAMES, MAX_PDU_DATA> = PduStorage::new();

struct Unpark(Thread);

impl Wake for Unpark {
    fn wake(self: Arc<Self>) {
        self.0.unpark();
    }
}

fn description(product: u32, name: &str) -> DeviceDescription {
    DeviceDescription {
        vendor_id: 0x0000_0A5A,
        product_code: product,
        revision: 3,
        serial: 1000 + product,
        order_code: format!("SIM-{product:X}"),
        name: name.into(),
        mailbox: None,
        mailbox_protocols: 0,
        sync_managers: vec![],
        fmmus: vec![],
        dc: false,
    }
}

#[test]
fn ethercrab_scans_the_simulated_chain() {
    let mut chain = SlaveChain::new(vec![
        Slave::new(description(0x10, "sim drive A")),
        Slave::new(description(0x11, "sim drive B")),
        Slave::new(description(0x20, "sim encoder")),
    ]);
    let (mut tx, mut rx, pdu_loop) = PDU_STORAGE.try_split().expect("split once");
    let stop = Arc::new(AtomicBool::new(false));
    let stop_io = stop.clone();
    let io = std::thread::spawn(move || {
        let waker = Waker::from(Arc::new(Unpark(std::thread::current())));
        let mut frames = 0u64;
        while !stop_io.load(Ordering::Relaxed) {
            tx.replace_waker(&waker);
            let mut sent = false;
            while let Some(frame) = tx.next_sendable_frame() {
                let mut wire = Vec::new();
                frame
                    .send_blocking(|bytes| {
                        wire.extend_from_slice(bytes);
                        Ok(bytes.len())
                    })
                    .expect("send");
                // Only after send_blocking has returned may the reply be received.
                chain.process(&mut wire).expect("well-formed frame");
                rx.receive_frame(&wire).expect("reply accepted");
                frames += 1;
                sent = true;
            }
            if !sent {
                std::thread::park_timeout(Duration::from_millis(1));
            }
        }
        (frames, chain)
    });
    let maindevice = MainDevice::new(pdu_loop, Timeouts::default(), MainDeviceConfig::default());
    let result = futures_lite::future::block_on(async {
        let group = maindevice
            .init_single_group::<MAX_SUBDEVICES, PDI_LEN>(ethercat_now)
            .await?;
        let mut seen = Vec::new();
        for sd in group.iter(&maindevice) {
            seen.push((
                sd.configured_address(),
                sd.identity().vendor_id,
                sd.identity().product_id,
                sd.name().to_string(),
                sd.description()
                    .await?
                    .map(|d| d.to_string())
                    .unwrap_or_default(),
            ));
        }
        let group = group.into_op(&maindevice).await?;
        let mut all_op = true;
        for sd in group.iter(&maindevice) {
            let (state, _code) = sd.status().await?;
            all_op &= state == ethercrab::SubDeviceState::Op;
        }
        Ok::<_, ethercrab::error::Error>((seen, all_op))
    });
    stop.store(true, Ordering::Relaxed);
    let (frames, chain) = io.join().expect("io thread");
    let (seen, all_op) = result.expect("ethercrab brings the simulated slaves up");
    assert_eq!(seen.len(), 3);
    assert_eq!(
        seen[0],
        (
            0x1000,
            0x0A5A,
            0x10,
            "SIM-10".to_string(),
            "sim drive A".to_string()
        )
    );
    assert_eq!(seen[2].2, 0x20);
    assert_eq!(seen[2].3, "SIM-20");
    assert_eq!(seen[2].4, "sim encoder");
    assert!(all_op, "every slave reports OP");
    for s in chain.slaves() {
        assert_eq!(s.al_status() & 0x0F, 8);
    }
    assert!(frames > 10, "{frames} frames exchanged");
}
