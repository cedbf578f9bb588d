//! gantry's EtherCAT master on ethercrab: the embedded bus (frames to a simulated chain in
//! this process) and the cyclic exchange that joins the kernel, the CiA-402 layer and the
//! process data.

pub mod bus;
pub mod coalesce;
pub mod cycle;
pub mod doorbell;
pub mod embedded;
pub mod frame;
pub mod health;
pub mod link;
pub mod mapping;
pub mod pump;
pub mod raw;
pub mod recovery;
pub mod transition;
