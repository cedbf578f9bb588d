//! CoE through the simulated mailbox: ethercrab finds the servo's PDO mapping by SDO
//! uploads of 0x1C12/0x1C13 and the mapping objects (the EEPROM lists no PDOs), sizes the
//! process image from them, and reads and writes objects with SDOs; aborts reach it as
//! errors.

use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage};
use gantry::ethercat::transition;
use gantry_sim::catalog;
use gantry_sim::chain::SlaveChain;
use gantry_sim::coe::od::ObjectDictionary;
use gantry_sim::esc::sii::DeviceDescription;
use gantry_sim::slave::Slave;
use gantry_tests::EmbeddedBus;

const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

/// The catalog servo's EEPROM (CoE mailbox, no PDOs listed), as a revision-2 device.
fn coe_servo() -> DeviceDescription {
    DeviceDescription {
        revision: 2,
        serial: 99,
        ..catalog::servo_description(99)
    }
}

#[test]
fn ethercrab_maps_pdos_and_uses_sdos_through_the_simulated_mailbox() {
    let od = ObjectDictionary::cia402_servo(0x0A5A, 0x0402, 2, 99);
    let chain = SlaveChain::new(vec![Slave::new(coe_servo()).with_coe(od)]);
    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().expect("split once");
    let bus = EmbeddedBus::start(tx, rx, chain);
    let chain = bus.chain.clone();
    let maindevice = MainDevice::new(
        pdu_loop,
        gantry_tests::lockstep_timeouts(),
        MainDeviceConfig::default(),
    );
    let result = futures_lite::future::block_on(async {
        let group = maindevice.init_single_group::<8, 64>(ethercat_now).await?;
        let sd = group.subdevice(&maindevice, 0)?;
        let product: u32 = sd.sdo_read(0x1018, 2).await?;
        let mode: i8 = sd.sdo_read(0x6060, 0).await?;
        sd.sdo_write(0x6060, 0, 9i8).await?;
        let mode_after: i8 = sd.sdo_read(0x6060, 0).await?;
        let missing = sd.sdo_read::<u32>(0x2000, 0).await.is_err();
        let read_only = sd.sdo_write(0x1000, 0, 0u32).await.is_err();
        let group = transition::into_op(
            group.into_safe_op(&maindevice).await?,
            &maindevice,
            transition::OP_TIMEOUT,
        )
        .await?;
        let sd = group.subdevice(&maindevice, 0)?;
        let sizes = (sd.inputs_raw().len(), sd.outputs_raw().len());
        Ok::<_, ethercrab::error::Error>((product, mode, mode_after, missing, read_only, sizes))
    });
    bus.stop();
    let (product, mode, mode_after, missing, read_only, sizes) =
        result.expect("CoE works through the simulated mailbox");
    assert_eq!(product, 0x0402);
    assert_eq!((mode, mode_after), (8, 9));
    assert!(missing, "a missing object aborts");
    assert!(read_only, "writing a read-only object aborts");
    assert_eq!(
        sizes,
        (6, 6),
        "process image sized from the PDO mapping read by SDO"
    );
    let c = chain.lock().unwrap();
    let od = c.slaves()[0].object_dictionary().unwrap();
    assert_eq!(od.read(0x6060, 0), Ok(&[9u8][..]));
}
