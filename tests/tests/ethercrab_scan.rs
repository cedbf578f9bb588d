//! An independent master — ethercrab, which no one here wrote — scans the simulated slave
//! chain in the same process: it counts the slaves, gives them addresses, reads their
//! identity and names from the emulated EEPROM, and walks them through the AL states to OP.

use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage};
use gantry::ethercat::transition;
use gantry_sim::chain::SlaveChain;
use gantry_sim::esc::sii::DeviceDescription;
use gantry_sim::slave::Slave;
use gantry_tests::EmbeddedBus;

const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

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
        tx_pdos: vec![],
        rx_pdos: vec![],
    }
}

#[test]
fn ethercrab_scans_the_simulated_chain() {
    let chain = SlaveChain::new(vec![
        Slave::new(description(0x10, "sim drive A")),
        Slave::new(description(0x11, "sim drive B")),
        Slave::new(description(0x20, "sim encoder")),
    ]);
    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().expect("split once");
    let bus = EmbeddedBus::start(tx, rx, chain);
    let maindevice = MainDevice::new(
        pdu_loop,
        gantry_tests::lockstep_timeouts(),
        MainDeviceConfig::default(),
    );
    let result = futures_lite::future::block_on(async {
        let group = maindevice.init_single_group::<8, 64>(ethercat_now).await?;
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
        let group = transition::into_op(
            group.into_safe_op(&maindevice).await?,
            &maindevice,
            transition::OP_TIMEOUT,
        )
        .await?;
        let mut all_op = true;
        for sd in group.iter(&maindevice) {
            let (state, _code) = sd.status().await?;
            all_op &= state == ethercrab::SubDeviceState::Op;
        }
        Ok::<_, ethercrab::error::Error>((seen, all_op))
    });
    let chain = bus.chain.clone();
    let frames = bus.stop();
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
    for s in chain.lock().unwrap().slaves() {
        assert_eq!(s.al_status() & 0x0F, 8);
    }
    assert!(frames > 10, "{frames} frames exchanged");
}
