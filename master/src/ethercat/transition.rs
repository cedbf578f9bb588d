//! Taking a group to Op the way drives need it. A drive in SafeOp goes to Op only once it
//! has valid outputs, i.e. its output SyncManager's buffer was written at least once
//! since SafeOp (ETG.1000.6 §6.4.1; the slave stack code's `OP_PD_REQUIRED`), and it
//! takes milliseconds to get there. ethercrab's `into_op` requests Op and polls AL status
//! without sending process data, so such a drive never gets there: here the master
//! requests Op and keeps the process data running until every slave reports Op.

use std::time::{Duration, Instant};

use ethercrab::error::{Error, TimeoutError};
use ethercrab::subdevice_group::{Op, SafeOp};
use ethercrab::{MainDevice, SubDeviceGroup};

/// How long the slaves get to reach Op: ethercrab's own state-transition timeout.
pub const OP_TIMEOUT: Duration = Duration::from_secs(5);

/// Requests Op for every slave of `group` (in SafeOp) and runs the process data (outputs
/// as they are in the group's image, zero unless the caller set them) until all report
/// Op, at most `timeout` (host time).
///
/// # Errors
/// A frame that could not be exchanged, or `Timeout(StateTransition)` when a slave is not
/// in Op by then.
pub async fn into_op<const N: usize, const P: usize, DC>(
    group: SubDeviceGroup<N, P, ethercrab::DefaultLock, SafeOp, DC>,
    md: &MainDevice<'_>,
    timeout: Duration,
) -> Result<SubDeviceGroup<N, P, ethercrab::DefaultLock, Op, DC>, Error> {
    let group = group.request_into_op(md).await?;
    let start = Instant::now();
    loop {
        if group.tx_rx(md).await?.all_op() {
            return Ok(group);
        }
        if start.elapsed() > timeout {
            return Err(Error::Timeout(TimeoutError::StateTransition));
        }
    }
}
