//! Cyclic process data between ethercrab and a simulated slave with fixed PDOs (from its
//! EEPROM): ethercrab configures SyncManagers and FMMUs from the SII, and every LRW moves
//! its outputs into the slave's memory and the slave's inputs into its image.

use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage};
use gantry::ethercat::transition;
use gantry_sim::catalog::{INPUTS_AT, OUTPUTS_AT};
use gantry_sim::chain::SlaveChain;
use gantry_sim::esc::sii::DeviceDescription;
use gantry_sim::slave::Slave;
use gantry_tests::EmbeddedBus;

const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
static PDU_STORAGE: PduStorage<16, MAX_PDU_DATA> = PduStorage::new();

fn io_device() -> DeviceDescription {
    // Outputs: controlword + target position; inputs: statusword + position actual.
    gantry_tests::eeprom_pdo_device(
        7,
        &[(0x6040, 16), (0x607A, 32)],
        &[(0x6041, 16), (0x6064, 32)],
    )
}

#[test]
fn outputs_reach_the_slave_and_inputs_reach_the_master() {
    let chain = SlaveChain::new(vec![Slave::new(io_device())]);
    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().expect("split once");
    let bus = EmbeddedBus::start(tx, rx, chain);
    let maindevice = MainDevice::new(
        pdu_loop,
        gantry_tests::lockstep_timeouts(),
        MainDeviceConfig::default(),
    );
    let chain = bus.chain.clone();
    let result = futures_lite::future::block_on(async {
        let group = maindevice.init_single_group::<8, 64>(ethercat_now).await?;
        let group = transition::into_op(
            group.into_safe_op(&maindevice).await?,
            &maindevice,
            transition::OP_TIMEOUT,
        )
        .await?;
        let sd = group.subdevice(&maindevice, 0)?;
        let (in_len, out_len) = (sd.inputs_raw().len(), sd.outputs_raw().len());
        sd.io_raw_mut()
            .outputs()
            .copy_from_slice(&[0x0F, 0x00, 0x78, 0x56, 0x34, 0x12]);
        chain
            .lock()
            .unwrap()
            .slave_mut(0)
            .unwrap()
            .write_process_ram(INPUTS_AT, &[0x37, 0x06, 0x01, 0x02, 0x03, 0x04]);
        for _ in 0..3 {
            group.tx_rx(&maindevice).await?;
        }
        let inputs = sd.inputs_raw().to_vec();
        Ok::<_, ethercrab::error::Error>((in_len, out_len, inputs))
    });
    let slave_outputs = {
        let c = chain.lock().unwrap();
        let mut b = [0u8; 6];
        c.slaves()[0].memory().ecat_read(OUTPUTS_AT, &mut b, false);
        b
    };
    bus.stop();
    let (in_len, out_len, inputs) = result.expect("process data runs");
    assert_eq!((in_len, out_len), (6, 6), "sizes from the EEPROM's PDOs");
    assert_eq!(inputs, vec![0x37, 0x06, 0x01, 0x02, 0x03, 0x04]);
    assert_eq!(slave_outputs, [0x0F, 0x00, 0x78, 0x56, 0x34, 0x12]);
}
