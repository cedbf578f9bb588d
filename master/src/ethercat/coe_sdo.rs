//! SDO transfers over CoE (ETG.1000.6 §5.6.2) while the slaves are in OP: a state machine
//! that issues at most one mailbox register access per cycle, beside the process data
//! and under the cycle's deadline, as [`super::recovery::Recovery`] does for AL states —
//! so a transfer never stretches a cycle, whatever the drive takes to answer.
//!
//! The mailbox is the one the bring-up set up, read back from the slave's SyncManager 0
//! (master → slave) and 1 (slave → master) registers. A request is written as a whole
//! SM0 area (the ESC completes a mailbox write on its last byte, ESC datasheet section I
//! §8.2); the answer is awaited by polling the SM1 status' "mailbox full" bit and then
//! read as a whole SM1 area (which empties it). A write whose frame was lost is written
//! again with the same counter: a slave discards a mailbox whose counter repeats the
//! previous one (ETG.1000.6 Table 29), so a request that did arrive is not served twice.
//! A write the ESC refuses (working counter 0: SM0 still full) is not simply written
//! again: the firmware takes SM0 only once SM1 is free, and what waits in SM0 may be this
//! very request (a repeat whose reply was lost too) behind its own answer in SM1 — so
//! SM1's status is looked at first, and an answer there is read (as SOEM empties a
//! slave's send mailbox before it writes).
//!
//! Expedited (≤ 4 bytes), normal (the data in the initiate message) and segmented
//! (toggle bit alternating, ETG.1000.6 §5.6.2.3–2.6) uploads and downloads; complete
//! access is not used. A segment fills the mailbox, one segment a mailbox round trip.
//! The data is in the [`SdoBuffer`] lent with the transfer, capped at its capacity: a
//! larger upload is aborted at the slave (0x05040005 out of memory) and reported with its
//! size. The slave may take [`SdoTransfer::timeout_ns`] for each answer. Nothing here
//! allocates: the messages are built in and read from buffers the bus owns.

use ethercrab::error::Error as EcError;
use ethercrab::{Command, MainDevice};
use gantry_drives::canopen::sdo::abort::AbortCode;

use crate::runtime::sdo::{SdoBuffer, SdoDirection, SdoError, SdoTransfer};

/// SyncManager 0's registers (ETG.1000.4 §6.7.2, Table 58); SyncManager n at + 8·n.
pub const SM0: u16 = 0x0800;
/// Bytes of one SyncManager's registers.
pub const SM_REGISTERS: usize = 8;
/// Offset of the status register in a SyncManager's registers.
pub const SM_STATUS: u16 = 5;
/// Status bit 3 in mailbox mode: the mailbox is full.
pub const SM_STATUS_MAILBOX_FULL: u8 = 0x08;
/// Control bits 1:0 = 10: mailbox mode (one buffer).
const SM_MODE_MAILBOX: u8 = 0x02;
/// Control bits 3:2: direction; 01 the master writes (ECAT write), 00 the master reads.
const SM_DIRECTION_MASK: u8 = 0x0C;
const SM_DIRECTION_WRITE: u8 = 0x04;
/// Offset of the activate register in a SyncManager's registers.
pub const SM_ACTIVATE: u16 = 6;
/// Activate register bit 0: the SyncManager is enabled.
const SM_ENABLE: u8 = 0x01;
/// Activate register bit 1 of a read mailbox: repeat request. Toggled by the master when
/// the frame that read an answer was lost after the ESC emptied the mailbox; the slave
/// puts its last answer back (ESC datasheet section I §8.6, ETG.1000.4 §6.7.2).
pub const SM_REPEAT: u8 = 0x02;

/// Mailbox header length (ETG.1000.6 Table 29: length, address, channel/priority,
/// type/counter).
pub const MAILBOX_HEADER: usize = 6;
/// Mailbox type: error reply (ETG.1000.6 Table 30).
pub const MAILBOX_TYPE_ERROR: u8 = 0x00;
/// Mailbox type: CoE.
pub const MAILBOX_TYPE_COE: u8 = 0x03;
/// CoE header length (number, service).
pub const COE_HEADER: usize = 2;
/// CoE service: emergency (ETG.1000.6 Table 40).
pub const COE_EMERGENCY: u16 = 1;
/// CoE service: SDO request (also the service of an abort, either way).
pub const COE_SDO_REQUEST: u16 = 2;
/// CoE service: SDO response.
pub const COE_SDO_RESPONSE: u16 = 3;
/// Where the SDO command byte sits in a mailbox.
const SDO_AT: usize = MAILBOX_HEADER + COE_HEADER;
/// SDO header of initiate messages: command, index, sub-index, 4 data or size bytes.
const SDO_INITIATE: usize = 8;
/// Bytes of a segment's data that fill a segment message without padding (CiA 301:
/// shorter segments are padded to 7 and say how many bytes are unused).
const SEGMENT_MIN: usize = 7;

/// Largest mailbox (SM0 or SM1 length) this client serves: drives' mailboxes are 128 to
/// 1024 bytes, and a whole one goes in one datagram beside the process data.
pub const MAX_MAILBOX: usize = 1024;
/// Bytes of an answer kept: a whole mailbox (a segment fills it).
pub const ANSWER_KEEP: usize = MAX_MAILBOX;
/// Smallest mailbox that holds an initiate message.
const MIN_MAILBOX: usize = SDO_AT + SDO_INITIATE;

/// Out of memory (CiA 301 Table 22): the master's reason to abort an upload too large.
const ABORT_OUT_OF_MEMORY: AbortCode = AbortCode::OUT_OF_MEMORY;

/// A slave's mailbox as its SyncManagers 0 and 1 are set up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mailbox {
    /// SM0's physical start address: the master writes requests here.
    pub write_at: u16,
    /// SM0's length.
    pub write_len: u16,
    /// SM1's physical start address: the master reads answers here.
    pub read_at: u16,
    /// SM1's length.
    pub read_len: u16,
    /// SM1's activate register as the master last wrote it (its repeat request bit
    /// toggles with each repeat).
    pub read_activate: u8,
}

impl Mailbox {
    /// The mailbox of the SyncManager 0 and 1 registers in `regs` (16 bytes from 0x0800):
    /// `None` unless both are enabled in mailbox mode, SM0 written by the master and SM1
    /// read by it, each between an initiate message and [`MAX_MAILBOX`] bytes long.
    pub fn from_sync_managers(regs: &[u8; 2 * SM_REGISTERS]) -> Option<Self> {
        let sm = |n: usize| {
            let r = regs.get(n * SM_REGISTERS..(n + 1) * SM_REGISTERS)?;
            let (start, len) = (
                u16::from_le_bytes([r[0], r[1]]),
                u16::from_le_bytes([r[2], r[3]]),
            );
            let (control, activate) = (r[4], r[6]);
            let fits = (MIN_MAILBOX..=MAX_MAILBOX).contains(&usize::from(len));
            let mailbox = control & 0x03 == SM_MODE_MAILBOX && activate & SM_ENABLE != 0;
            (fits && mailbox).then_some((start, len, control & SM_DIRECTION_MASK, activate))
        };
        match (sm(0)?, sm(1)?) {
            (
                (write_at, write_len, SM_DIRECTION_WRITE, _),
                (read_at, read_len, 0, read_activate),
            ) => Some(Self {
                write_at,
                write_len,
                read_at,
                read_len,
                read_activate,
            }),
            _ => None,
        }
    }

    /// SM1's status register.
    const fn read_status(&self) -> u16 {
        SM0 + SM_REGISTERS as u16 + SM_STATUS
    }

    /// SM1's activate register.
    const fn read_activate_register(&self) -> u16 {
        SM0 + SM_REGISTERS as u16 + SM_ACTIVATE
    }
}

/// The one mailbox access a transfer wants next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MailboxAccess {
    /// FPWR of the first `len` bytes of the bus' message buffer at `at` (all of SM0).
    Write {
        /// SM0's start.
        at: u16,
        /// SM0's length.
        len: u16,
    },
    /// FPRD of one byte: SM1's status.
    ReadStatus {
        /// The register.
        at: u16,
    },
    /// FPWR of SM1's activate register with the repeat request toggled: the slave puts
    /// the answer whose read was lost back.
    Repeat {
        /// The register.
        at: u16,
        /// Its new value.
        value: u8,
    },
    /// FPRD of `len` bytes at `at` (all of SM1), kept in the bus' answer buffer.
    Read {
        /// SM1's start.
        at: u16,
        /// SM1's length.
        len: u16,
    },
}

/// What the slave answered to a [`MailboxAccess`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MailboxAnswer {
    /// The write was taken (working counter 1).
    Written,
    /// The ESC refused the access (working counter 0): a write to a full SM0, a read of
    /// an empty SM1.
    Refused,
    /// SM1's status register.
    Status(u8),
    /// SM1 was read; its first bytes are in the answer buffer.
    Read,
    /// No answer: the frame was lost or timed out.
    None,
}

/// Runs `access` on the slave at station `address`: one register round trip. A write
/// sends `message`; a read keeps what fits of the mailbox in `answer`.
pub async fn mailbox_access(
    md: &MainDevice<'_>,
    address: u16,
    access: MailboxAccess,
    message: &[u8],
    answer: &mut [u8],
) -> MailboxAnswer {
    let judged = |e: EcError| match e {
        EcError::WorkingCounter { .. } => MailboxAnswer::Refused,
        _ => MailboxAnswer::None,
    };
    match access {
        MailboxAccess::Write { at, len } => {
            let Some(bytes) = message.get(..usize::from(len)) else {
                return MailboxAnswer::None;
            };
            Command::fpwr(address, at)
                .send_receive_slice(md, bytes)
                .await
                .map_or_else(judged, |_| MailboxAnswer::Written)
        }
        MailboxAccess::Repeat { at, value } => Command::fpwr(address, at)
            .send_receive_slice(md, &[value][..])
            .await
            .map_or_else(judged, |_| MailboxAnswer::Written),
        MailboxAccess::ReadStatus { at } => Command::fprd(address, at)
            .receive::<u8>(md)
            .await
            .map_or_else(judged, MailboxAnswer::Status),
        MailboxAccess::Read { at, len } => {
            match Command::fprd(address, at).receive_slice(md, len).await {
                Ok(read) => {
                    let n = read.len().min(answer.len());
                    if let (Some(dst), Some(src)) = (answer.get_mut(..n), read.get(..n)) {
                        dst.copy_from_slice(src);
                    }
                    MailboxAnswer::Read
                }
                Err(e) => judged(e),
            }
        }
    }
}

/// The next mailbox counter after `counter` (ETG.1000.6 Table 29: 1 to 7, then 1 again;
/// 0 is the start value).
pub const fn next_counter(counter: u8) -> u8 {
    if counter >= 7 {
        1
    } else {
        counter + 1
    }
}

/// The message a transfer sends next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Message {
    /// Initiate upload or download.
    Initiate,
    /// Upload segment request with this toggle.
    UploadSegment(bool),
    /// Download segment with this toggle.
    DownloadSegment(bool),
    /// Abort with this code; the transfer then ends with `then`.
    Abort(AbortCode, SdoError),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    /// Write the message (again, while the ESC refuses it or the frame is lost).
    Send(Message),
    /// Poll SM1's status for the answer to this message.
    Await(Message),
    /// Read SM1: the answer to this message is there.
    Read(Message),
    /// The read of the answer to this message was lost: ask the slave to put it back.
    Repeat(Message),
    /// The write of this message was refused (SM0 full): look at SM1 — an answer there
    /// (to this message, or a late one) keeps the firmware from taking SM0 until read.
    Peek(Message),
    /// Finished (an upload's bytes are in the buffer).
    Done(Result<(), SdoError>),
}

/// One SDO transfer to one slave (see the module doc). No allocation, no clock of its
/// own: the caller passes the time, and the transfer's buffer to each step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CoeSdo {
    mailbox: Mailbox,
    transfer: SdoTransfer,
    step: Step,
    /// The counter of the message in [`Step::Send`]/[`Step::Await`] (the last one used).
    counter: u8,
    /// When the slave last answered (at first, when the transfer started): it may stay
    /// silent for the transfer's timeout from then.
    heard_ns: u64,
    /// Upload: the size announced. Download: bytes the slave has taken so far.
    size: u32,
    sent: usize,
    /// The transfer before this one timed out with its request out: its answer may
    /// still come, so an initiate answer that is not this transfer's is passed over.
    late_answer_possible: bool,
    /// A write of the current message was taken (working counter 1).
    taken: bool,
    /// A write of the current message was taken or lost on the way (it may have arrived).
    maybe_out: bool,
    /// This transfer timed out with a request out (see `late_answer_possible`).
    left_unanswered: bool,
}

impl CoeSdo {
    /// A transfer through `mailbox`, started at `now_ns`; its first message carries the
    /// counter after `last_counter` (0 when this client has not used the slave's mailbox
    /// before: the bring-up's messages used counters this client cannot know, and 0, the
    /// start value, never repeats one of them).
    pub fn new(
        mailbox: Mailbox,
        transfer: SdoTransfer,
        last_counter: Option<u8>,
        now_ns: u64,
    ) -> Self {
        Self {
            mailbox,
            transfer,
            step: Step::Send(Message::Initiate),
            counter: last_counter.map_or(0, next_counter),
            heard_ns: now_ns,
            size: 0,
            sent: 0,
            late_answer_possible: false,
            left_unanswered: false,
            taken: false,
            maybe_out: false,
        }
    }

    /// The same transfer, told that the one before it timed out with its request out
    /// ([`CoeSdo::left_unanswered`]): an initiate answer that is not for this request (another
    /// object, another command) is that late answer and passed over, instead of a
    /// protocol error.
    pub fn after_unanswered(mut self, late_answer_possible: bool) -> Self {
        self.late_answer_possible = late_answer_possible;
        self
    }

    /// Whether it timed out with a request out, whose answer may still come.
    pub fn left_unanswered(&self) -> bool {
        self.left_unanswered
    }

    /// The counter of the last message sent (the next transfer starts after it).
    pub fn counter(&self) -> u8 {
        self.counter
    }

    /// The mailbox as this transfer leaves it (the repeat request bit it toggled).
    pub fn mailbox(&self) -> Mailbox {
        self.mailbox
    }

    /// The outcome, once finished (an upload's bytes are in the buffer).
    pub fn outcome(&self) -> Option<Result<(), SdoError>> {
        match self.step {
            Step::Done(r) => Some(r),
            _ => None,
        }
    }

    /// The access to run next (`None` once finished); for a write, the message is built
    /// in `message` (at least SM0's length), a download's from `data`.
    pub fn next_access(&self, message: &mut [u8], data: &[u8]) -> Option<MailboxAccess> {
        let m = &self.mailbox;
        match self.step {
            Step::Send(msg) => {
                self.build(msg, message, data)?;
                Some(MailboxAccess::Write {
                    at: m.write_at,
                    len: m.write_len,
                })
            }
            Step::Await(_) | Step::Peek(_) => Some(MailboxAccess::ReadStatus {
                at: m.read_status(),
            }),
            Step::Read(_) => Some(MailboxAccess::Read {
                at: m.read_at,
                len: m.read_len,
            }),
            Step::Repeat(_) => Some(MailboxAccess::Repeat {
                at: m.read_activate_register(),
                value: m.read_activate,
            }),
            Step::Done(_) => None,
        }
    }

    /// Takes the answer to [`CoeSdo::next_access`] (`answer`: the answer buffer after a
    /// read), received at `now_ns`; an upload's bytes go to `buffer`.
    pub fn on_answer(
        &mut self,
        got: MailboxAnswer,
        answer: &[u8],
        buffer: &mut SdoBuffer,
        now_ns: u64,
    ) {
        let sending = matches!(self.step, Step::Send(_));
        if sending && matches!(got, MailboxAnswer::Written | MailboxAnswer::None) {
            self.maybe_out = true;
        }
        self.step = match (self.step, got) {
            (Step::Done(r), _) => Step::Done(r),
            (Step::Send(Message::Abort(_, then)), MailboxAnswer::Written) => Step::Done(Err(then)),
            (Step::Send(msg), MailboxAnswer::Written) => Step::Await(msg),
            (Step::Send(msg), MailboxAnswer::Refused) => Step::Peek(msg),
            (Step::Await(msg) | Step::Peek(msg), MailboxAnswer::Status(s))
                if s & SM_STATUS_MAILBOX_FULL != 0 =>
            {
                Step::Read(msg)
            }
            // Nothing in SM1: the firmware is still busy with SM0; write again.
            (Step::Peek(msg), MailboxAnswer::Status(_)) => Step::Send(msg),
            // An answer read before an abort could be written: the abort goes still.
            (Step::Read(msg @ Message::Abort(..)), MailboxAnswer::Read) => Step::Send(msg),
            (Step::Read(msg), MailboxAnswer::Read) => match self.on_message(msg, answer, buffer) {
                Step::Await(m) => self.wait_for(m),
                step => {
                    // The slave answered this message: its next answer is timed from now.
                    self.heard_ns = now_ns;
                    step
                }
            },
            // An empty SM1 after all (another reader?): wait again.
            (Step::Read(msg), MailboxAnswer::Refused) => self.wait_for(msg),
            // The frame that read it was lost: the ESC may have emptied SM1 on the way
            // out. Ask for the answer again (the request toggled once; written again
            // unchanged while refused or lost, a no-op if it had arrived).
            (Step::Read(msg), MailboxAnswer::None) => {
                self.mailbox.read_activate ^= SM_REPEAT;
                Step::Repeat(msg)
            }
            (Step::Repeat(msg), MailboxAnswer::Written) => self.wait_for(msg),
            // Refused, lost, not there yet: the same again.
            (step, _) => step,
        };
        if sending && got == MailboxAnswer::Written {
            self.taken = true;
        }
        self.tick(now_ns);
    }

    /// After an answer that was not this message's (or none): wait for it if the slave
    /// took the message, else write it (again: a repeat that did arrive is discarded by
    /// its counter).
    fn wait_for(&self, msg: Message) -> Step {
        if self.taken {
            Step::Await(msg)
        } else {
            Step::Send(msg)
        }
    }

    /// Ends the transfer once the slave has been silent for its timeout (call in cycles
    /// without an access of its own, too).
    pub fn tick(&mut self, now_ns: u64) {
        let waited_ns = now_ns.saturating_sub(self.heard_ns);
        if matches!(self.step, Step::Done(_)) || waited_ns < self.transfer.timeout_ns {
            return;
        }
        self.left_unanswered = self.maybe_out
            || matches!(self.step, Step::Await(_) | Step::Read(_) | Step::Repeat(_))
            || self.late_answer_possible;
        self.step = Step::Done(Err(SdoError::timed_out(&self.transfer, waited_ns)));
    }

    fn protocol(&self, what: &'static str) -> SdoError {
        SdoError::protocol(&self.transfer, what)
    }

    /// Ends with `error`, telling the slave first (an abort message).
    fn abort(&self, code: AbortCode, error: SdoError) -> Step {
        Step::Send(Message::Abort(code, error))
    }

    /// The next step after the answer to `msg` arrived in `answer` (an upload's bytes
    /// go to `buffer`).
    fn on_message(&mut self, msg: Message, answer: &[u8], buffer: &mut SdoBuffer) -> Step {
        let byte = |i: usize| answer.get(i).copied().unwrap_or(0);
        let word = |i: usize| u16::from_le_bytes([byte(i), byte(i + 1)]);
        let long = |i: usize| u32::from_le_bytes([byte(i), byte(i + 1), byte(i + 2), byte(i + 3)]);
        let len = usize::from(word(0));
        let kind = byte(5) & 0x0F;
        if kind == MAILBOX_TYPE_ERROR {
            return Step::Done(Err(self.protocol(
                "the slave answered with a mailbox error (ETG.1000.6 Table 31): it does not \
                 take CoE SDO requests",
            )));
        }
        let service = word(MAILBOX_HEADER) >> 12;
        // Another protocol's mail, or an emergency: not the answer; wait on.
        if kind != MAILBOX_TYPE_COE || service == COE_EMERGENCY || len < COE_HEADER + 1 {
            return Step::Await(msg);
        }
        let cmd = byte(SDO_AT);
        let t = self.transfer;
        if service == COE_SDO_REQUEST && cmd >> 5 == 4 {
            return Step::Done(Err(SdoError::aborted(&t, AbortCode(long(SDO_AT + 4)))));
        }
        if service != COE_SDO_RESPONSE {
            return Step::Await(msg);
        }
        let scs = cmd >> 5;
        let names_object = word(SDO_AT + 1) == t.index && byte(SDO_AT + 3) == t.sub;
        // The SDO part of the message: from the command byte to the mailbox' length.
        let end = (MAILBOX_HEADER + len).min(answer.len());
        match (msg, t.direction) {
            (Message::Initiate, SdoDirection::Upload) => {
                if !names_object || (scs != 2 && self.late_answer_possible) {
                    // A late answer to an earlier transfer (one that timed out): not ours.
                    return Step::Await(msg);
                }
                if scs != 2 {
                    return Step::Done(Err(self.protocol(
                        "the answer to the upload request is not its initiate response",
                    )));
                }
                let expedited = cmd & 0x02 != 0;
                let sized = cmd & 0x01 != 0;
                if expedited {
                    let unused = if sized {
                        usize::from((cmd >> 2) & 0x03)
                    } else {
                        0
                    };
                    let at = SDO_AT + 4;
                    let data = answer.get(at..at + 4 - unused).unwrap_or_default();
                    if !buffer.fill(data) {
                        let size = data.len() as u32;
                        return Step::Done(Err(SdoError::too_large(
                            &t,
                            Some(size),
                            buffer.capacity(),
                        )));
                    }
                    return Step::Done(Ok(()));
                }
                self.size = long(SDO_AT + 4);
                if self.size as usize > buffer.capacity() {
                    let e = SdoError::too_large(&t, Some(self.size), buffer.capacity());
                    return self.abort(ABORT_OUT_OF_MEMORY, e);
                }
                let at = SDO_AT + SDO_INITIATE;
                let here = answer.get(at..end.max(at)).unwrap_or_default();
                let take = here.len().min(self.size as usize);
                buffer.clear();
                buffer.extend(here.get(..take).unwrap_or_default());
                if buffer.len() >= self.size as usize {
                    Step::Done(Ok(()))
                } else {
                    self.next(Message::UploadSegment(false))
                }
            }
            (Message::UploadSegment(toggle), SdoDirection::Upload) => {
                if scs != 0 {
                    return Step::Done(Err(
                        self.protocol("the answer to an upload segment request is not a segment")
                    ));
                }
                if (cmd & 0x10 != 0) != toggle {
                    return self.abort(
                        AbortCode::TOGGLE_BIT_NOT_ALTERNATED,
                        self.protocol("the upload segment's toggle bit did not alternate"),
                    );
                }
                let at = SDO_AT + 1;
                let mut seg = answer.get(at..end.max(at)).unwrap_or_default();
                if seg.len() == SEGMENT_MIN {
                    let unused = usize::from((cmd >> 1) & 0x07);
                    seg = seg.get(..SEGMENT_MIN - unused).unwrap_or_default();
                }
                let last = cmd & 0x01 != 0;
                if buffer.len() + seg.len() > self.size as usize || !buffer.extend(seg) {
                    return self.abort(
                        AbortCode::LENGTH_TOO_HIGH,
                        self.protocol("the upload segments carry more than the size announced"),
                    );
                }
                match (last, buffer.len() == self.size as usize) {
                    (true, true) => Step::Done(Ok(())),
                    (true, false) => Step::Done(Err(
                        self.protocol("the upload segments carry less than the size announced")
                    )),
                    (false, _) => self.next(Message::UploadSegment(!toggle)),
                }
            }
            (Message::Initiate, SdoDirection::Download) => {
                if !names_object || (scs != 3 && self.late_answer_possible) {
                    // A late answer to an earlier transfer (one that timed out): not ours.
                    return Step::Await(msg);
                }
                if scs != 3 {
                    return Step::Done(Err(self.protocol(
                        "the answer to the download request is not its initiate response",
                    )));
                }
                self.sent = self.carried(msg, buffer.len());
                if self.sent >= buffer.len() {
                    Step::Done(Ok(()))
                } else {
                    self.next(Message::DownloadSegment(false))
                }
            }
            (Message::DownloadSegment(toggle), SdoDirection::Download) => {
                if scs != 1 || (cmd & 0x10 != 0) != toggle {
                    return Step::Done(Err(self.protocol(
                        "the answer to a download segment is not its response (toggle bit)",
                    )));
                }
                self.sent = self.carried(msg, buffer.len());
                if self.sent >= buffer.len() {
                    Step::Done(Ok(()))
                } else {
                    self.next(Message::DownloadSegment(!toggle))
                }
            }
            _ => Step::Done(Err(self.protocol("answer out of turn"))),
        }
    }

    /// Sends `msg` next, with a new counter.
    fn next(&mut self, msg: Message) -> Step {
        self.counter = next_counter(self.counter);
        (self.taken, self.maybe_out) = (false, false);
        Step::Send(msg)
    }

    /// Builds `msg` in `out` (the whole SM0 area, zero after the message), a download's
    /// from `data`. `None` if `out` is too short (a caller's mistake).
    fn build(&self, msg: Message, out: &mut [u8], data: &[u8]) -> Option<()> {
        let area = out.get_mut(..usize::from(self.mailbox.write_len))?;
        area.fill(0);
        let r = &self.transfer;
        let mut sdo = [0u8; SDO_INITIATE];
        let initiate = |cmd: u8, tail: [u8; 4]| {
            let [i0, i1] = r.index.to_le_bytes();
            [cmd, i0, i1, r.sub, tail[0], tail[1], tail[2], tail[3]]
        };
        let mut service = COE_SDO_REQUEST;
        // Bytes after the 8-byte SDO header (normal download data, segment data).
        let mut extra: &[u8] = &[];
        let mut sdo_len = SDO_INITIATE;
        match (msg, r.direction) {
            (Message::Initiate, SdoDirection::Upload) => sdo = initiate(0x40, [0; 4]),
            (Message::Initiate, SdoDirection::Download) => {
                let d = data;
                if (1..=4).contains(&d.len()) {
                    let mut tail = [0u8; 4];
                    tail.get_mut(..d.len())?.copy_from_slice(d);
                    sdo = initiate(0x23 | (((4 - d.len()) as u8) << 2), tail);
                } else {
                    // Normal transfer: size, then as much data as SM0 holds.
                    sdo = initiate(0x21, (d.len() as u32).to_le_bytes());
                    let room = area.len() - SDO_AT - SDO_INITIATE;
                    extra = d.get(..d.len().min(room))?;
                }
            }
            (Message::UploadSegment(toggle), _) => sdo[0] = 0x60 | (u8::from(toggle) << 4),
            (Message::DownloadSegment(toggle), SdoDirection::Download) => {
                let rest = data.get(self.sent..)?;
                let room = area.len() - SDO_AT - 1;
                let chunk = rest.len().min(room);
                let last = chunk == rest.len();
                let unused = SEGMENT_MIN.saturating_sub(chunk) as u8;
                sdo[0] = (u8::from(toggle) << 4) | (unused << 1) | u8::from(last);
                extra = rest.get(..chunk)?;
                sdo_len = 1;
            }
            (Message::Abort(code, _), _) => {
                sdo = initiate(0x80, code.0.to_le_bytes());
                service = COE_SDO_REQUEST;
            }
            (Message::DownloadSegment(_), SdoDirection::Upload) => return None,
        }
        // A segment's data follows its command byte, padded to 7 bytes.
        let body = if sdo_len == 1 {
            1 + extra.len().max(SEGMENT_MIN)
        } else {
            SDO_INITIATE + extra.len()
        };
        let length = (COE_HEADER + body) as u16;
        area.get_mut(0..2)?.copy_from_slice(&length.to_le_bytes());
        *area.get_mut(5)? = MAILBOX_TYPE_COE | (self.counter << 4);
        area.get_mut(MAILBOX_HEADER..SDO_AT)?
            .copy_from_slice(&(service << 12).to_le_bytes());
        area.get_mut(SDO_AT..SDO_AT + sdo_len)?
            .copy_from_slice(sdo.get(..sdo_len)?);
        let at = SDO_AT + sdo_len;
        area.get_mut(at..at + extra.len())?.copy_from_slice(extra);
        Some(())
    }

    /// Download: how far the data went once the slave answered `msg` (counted on the
    /// answer, not on the write: a write may have arrived although its reply was lost).
    fn carried(&self, msg: Message, data_len: usize) -> usize {
        let w = usize::from(self.mailbox.write_len);
        match msg {
            Message::Initiate if data_len > 4 => data_len.min(w - SDO_AT - SDO_INITIATE),
            Message::Initiate => data_len,
            Message::DownloadSegment(_) => (self.sent + (w - SDO_AT - 1)).min(data_len),
            Message::UploadSegment(_) | Message::Abort(..) => self.sent,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MAILBOX: Mailbox = Mailbox {
        write_at: 0x1000,
        write_len: 128,
        read_at: 0x1080,
        read_len: 128,
        read_activate: 0x01,
    };

    /// A transfer and its buffer, as the bus keeps them.
    struct Run {
        t: CoeSdo,
        buf: SdoBuffer,
    }

    impl Run {
        /// `transfer` through [`MAILBOX`] after counter `last`, with `data` to download.
        fn new(transfer: SdoTransfer, last: Option<u8>, data: &[u8]) -> Self {
            // 0x2F00: a large object; the others' buffer is what a procedure lends.
            let capacity = if transfer.index == 0x2F00 { 1024 } else { 256 };
            let mut buf = SdoBuffer::with_capacity(capacity);
            assert!(buf.fill(data));
            Self {
                t: CoeSdo::new(MAILBOX, transfer, last, 0),
                buf,
            }
        }

        fn on_answer(&mut self, got: MailboxAnswer, answer: &[u8], now: u64) {
            self.t.on_answer(got, answer, &mut self.buf, now);
        }

        fn next_access(&self) -> Option<MailboxAccess> {
            self.t
                .next_access(&mut [0; MAX_MAILBOX], self.buf.as_slice())
        }

        /// The outcome with the bytes uploaded (none for a download).
        fn outcome(&self) -> Option<Result<Vec<u8>, SdoError>> {
            let upload = self.t.transfer.direction == SdoDirection::Upload;
            self.t.outcome().map(|r| {
                r.map(|()| match upload {
                    true => self.buf.as_slice().to_vec(),
                    false => Vec::new(),
                })
            })
        }

        /// A copy, at the same point.
        fn fork(&self) -> Self {
            let mut buf = SdoBuffer::with_capacity(self.buf.capacity());
            assert!(buf.fill(self.buf.as_slice()));
            Self { t: self.t, buf }
        }
    }

    /// The bytes of the next write, and its access.
    fn written(t: &Run) -> (MailboxAccess, Vec<u8>) {
        let mut m = [0u8; MAX_MAILBOX];
        let a =
            t.t.next_access(&mut m, t.buf.as_slice())
                .expect("an access");
        (a, m[..usize::from(MAILBOX.write_len)].to_vec())
    }

    /// A mailbox answer: CoE `service`, SDO bytes `sdo`, counter 0.
    fn answer(service: u16, sdo: &[u8]) -> Vec<u8> {
        let mut m = vec![0u8; ANSWER_KEEP];
        m[0..2].copy_from_slice(&((COE_HEADER + sdo.len()) as u16).to_le_bytes());
        m[5] = MAILBOX_TYPE_COE;
        m[6..8].copy_from_slice(&(service << 12).to_le_bytes());
        m[8..8 + sdo.len()].copy_from_slice(sdo);
        m
    }

    /// Takes the write, finds SM1 full, reads `reply`.
    fn exchange(t: &mut Run, reply: &[u8], now: u64) {
        t.on_answer(MailboxAnswer::Written, &[], now);
        exchange_read(t, reply, now);
    }

    /// Finds SM1 full, reads `reply`.
    fn exchange_read(t: &mut Run, reply: &[u8], now: u64) {
        assert_eq!(
            t.next_access(),
            Some(MailboxAccess::ReadStatus { at: 0x080D })
        );
        t.on_answer(MailboxAnswer::Status(SM_STATUS_MAILBOX_FULL), &[], now);
        assert_eq!(
            t.next_access(),
            Some(MailboxAccess::Read {
                at: 0x1080,
                len: 128
            })
        );
        t.on_answer(MailboxAnswer::Read, reply, now);
    }

    #[test]
    fn the_mailbox_is_read_from_the_sync_manager_registers() {
        let mut regs = [0u8; 16];
        regs[..8].copy_from_slice(&[0x00, 0x10, 128, 0, 0x26, 0, 0x01, 0]);
        regs[8..].copy_from_slice(&[0x80, 0x10, 128, 0, 0x22, 0, 0x01, 0]);
        assert_eq!(Mailbox::from_sync_managers(&regs), Some(MAILBOX));
        // Disabled, buffered, the wrong way round, too small: no mailbox.
        for (at, value) in [(6, 0x00), (4, 0x24), (4, 0x22), (2, 8)] {
            let mut bad = regs;
            bad[at] = value;
            assert_eq!(Mailbox::from_sync_managers(&bad), None, "byte {at}");
        }
    }

    #[test]
    fn an_expedited_download_is_one_message_as_etg_1000_6_lays_it_out() {
        let t = Run::new(SdoTransfer::download(0, 0x6060, 0), None, &[0x08]);
        let (access, m) = written(&t);
        assert_eq!(
            access,
            MailboxAccess::Write {
                at: 0x1000,
                len: 128
            }
        );
        // Length 10, address 0, channel 0, type CoE with counter 0; CoE: SDO request;
        // command 0x2F (download, expedited, size indicated, 3 bytes unused).
        assert_eq!(
            &m[..16],
            &[10, 0, 0, 0, 0, 0x03, 0x00, 0x20, 0x2F, 0x60, 0x60, 0x00, 0x08, 0, 0, 0]
        );
        assert!(m[16..].iter().all(|&b| b == 0), "the rest of SM0 zero");
    }

    #[test]
    fn the_first_message_carries_the_counter_after_the_last_one() {
        let req = SdoTransfer::upload(0, 0x1018, 1);
        let (_, m) = written(&Run::new(req, Some(3), &[]));
        assert_eq!(m[5], 0x03 | (4 << 4));
        let (_, m) = written(&Run::new(req, Some(7), &[]));
        assert_eq!(m[5], 0x03 | (1 << 4), "after 7 comes 1, never 0");
        assert_eq!(&m[8..12], &[0x40, 0x18, 0x10, 0x01]);
    }

    #[test]
    fn a_lost_write_goes_again_unchanged() {
        let mut t = Run::new(SdoTransfer::upload(0, 0x1018, 1), Some(2), &[]);
        let first = written(&t);
        t.on_answer(MailboxAnswer::None, &[], 1);
        assert_eq!(
            written(&t),
            first,
            "lost: the same counter, a repeat if it arrived"
        );
        exchange(
            &mut t,
            &answer(COE_SDO_RESPONSE, &[0x43, 0x18, 0x10, 1, 0xAA, 0, 0, 0]),
            3,
        );
        assert_eq!(t.outcome(), Some(Ok(vec![0xAA, 0, 0, 0])));
    }

    #[test]
    fn a_refused_write_looks_at_sm1_and_goes_again_while_it_is_empty() {
        let mut t = Run::new(SdoTransfer::upload(0, 0x1018, 1), Some(2), &[]);
        let first = written(&t);
        t.on_answer(MailboxAnswer::Refused, &[], 1);
        let peek = MailboxAccess::ReadStatus { at: 0x080D };
        assert_eq!(t.next_access(), Some(peek));
        t.on_answer(MailboxAnswer::Status(0), &[], 2);
        assert_eq!(written(&t), first, "SM1 empty: the same message again");
    }

    /// The write arrived but its reply was lost; so did the repeat's, which waits in SM0
    /// behind the answer in SM1 (the firmware takes SM0 once SM1 is read); the next
    /// repeat is refused. Writing on would never end: the answer is read.
    #[test]
    fn a_refused_repeat_reads_the_answer_waiting_in_sm1() {
        let data = [7u8; 20];
        let mut t = Run::new(SdoTransfer::download(0, 0x2E00, 0), Some(2), &data);
        let (_, initiate) = written(&t);
        t.on_answer(MailboxAnswer::None, &[], 1);
        t.on_answer(MailboxAnswer::None, &[], 2);
        t.on_answer(MailboxAnswer::Refused, &[], 3);
        exchange_read(&mut t, &answer(COE_SDO_RESPONSE, &[0x60, 0, 0x2E, 0]), 4);
        // The data of a normal initiate went with it, although no write was seen taken:
        // the transfer is done (20 bytes fit the initiate message).
        assert_eq!(t.outcome(), Some(Ok(vec![])));
        assert_eq!(initiate[5] >> 4, 3, "the counter after 2");
    }

    /// A late answer of an earlier transfer found while this one's write is refused is
    /// passed over, and the request written (it was never taken).
    #[test]
    fn a_late_answer_found_by_a_refused_write_is_passed_over_and_the_write_goes_again() {
        let mut t = Run::new(SdoTransfer::upload(0, 0x1018, 1), Some(2), &[]);
        t.t = t.t.after_unanswered(true);
        let first = written(&t);
        t.on_answer(MailboxAnswer::Refused, &[], 1);
        exchange_read(
            &mut t,
            &answer(COE_SDO_RESPONSE, &[0x60, 0x00, 0x2E, 0, 0, 0, 0, 0]),
            2,
        );
        assert_eq!(t.outcome(), None);
        assert_eq!(written(&t), first);
    }

    #[test]
    fn a_lost_read_asks_for_the_answer_again_with_the_repeat_request() {
        let mut t = Run::new(SdoTransfer::upload(0, 0x1018, 1), None, &[]);
        t.on_answer(MailboxAnswer::Written, &[], 1);
        t.on_answer(MailboxAnswer::Status(SM_STATUS_MAILBOX_FULL), &[], 2);
        t.on_answer(MailboxAnswer::None, &[], 3);
        let repeat = MailboxAccess::Repeat {
            at: 0x080E,
            value: 0x03,
        };
        assert_eq!(t.next_access(), Some(repeat));
        // Lost again: the same value, not toggled back.
        t.on_answer(MailboxAnswer::None, &[], 4);
        assert_eq!(t.next_access(), Some(repeat));
        t.on_answer(MailboxAnswer::Written, &[], 5);
        exchange_read(
            &mut t,
            &answer(COE_SDO_RESPONSE, &[0x4F, 0x18, 0x10, 1, 7, 0, 0, 0]),
            6,
        );
        assert_eq!(t.outcome(), Some(Ok(vec![7])));
        assert_eq!(t.t.mailbox().read_activate, 0x03, "the bit stays toggled");
        // The next repeat toggles it back.
        let mut t = Run {
            t: CoeSdo::new(t.t.mailbox(), SdoTransfer::upload(0, 0x1018, 1), Some(1), 0),
            buf: SdoBuffer::with_capacity(256),
        };
        t.on_answer(MailboxAnswer::Written, &[], 1);
        t.on_answer(MailboxAnswer::Status(SM_STATUS_MAILBOX_FULL), &[], 2);
        t.on_answer(MailboxAnswer::None, &[], 3);
        assert_eq!(
            t.next_access(),
            Some(MailboxAccess::Repeat {
                at: 0x080E,
                value: 0x01
            })
        );
    }

    #[test]
    fn a_segmented_upload_alternates_the_toggle_and_checks_the_size() {
        let mut t = Run::new(SdoTransfer::upload(0, 0x1008, 0), None, &[]);
        // Normal initiate response: 12 bytes announced, 4 here.
        let mut init = vec![0x41, 0x08, 0x10, 0x00, 12, 0, 0, 0];
        init.extend(b"gant");
        exchange(&mut t, &answer(COE_SDO_RESPONSE, &init), 1);
        let (_, m) = written(&t);
        assert_eq!(&m[8..10], &[0x60, 0], "upload segment request, toggle 0");
        assert_eq!(m[5] >> 4, 1, "a new message, a new counter");
        // 5 bytes, padded to 7 (2 unused), not the last.
        exchange(
            &mut t,
            &answer(
                COE_SDO_RESPONSE,
                &[0x04, b'r', b'y', b' ', b's', b'i', 0, 0],
            ),
            2,
        );
        let (_, m) = written(&t);
        assert_eq!(m[8], 0x70, "toggle 1");
        // The toggle of the answer must be the request's.
        let mut stale = t.fork();
        exchange(
            &mut stale,
            &answer(COE_SDO_RESPONSE, &[0x01, b'm', 0, 0, 0, 0, 0, 0]),
            3,
        );
        let (_, m) = written(&stale);
        assert_eq!(
            (m[8], u32::from_le_bytes(m[12..16].try_into().unwrap())),
            (0x80, 0x0503_0000),
            "aborted at the slave: toggle bit not alternated"
        );
        stale.on_answer(MailboxAnswer::Written, &[], 4);
        assert!(matches!(
            stale.outcome(),
            Some(Err(SdoError::Protocol { .. }))
        ));
        // The last segment: 3 bytes (4 unused), toggle 1, last.
        exchange(
            &mut t,
            &answer(COE_SDO_RESPONSE, &[0x19, b'm', b'u', b'l', 0, 0, 0, 0]),
            3,
        );
        assert_eq!(t.outcome(), Some(Ok(b"gantry simul".to_vec())));
    }

    #[test]
    fn a_segmented_download_sends_what_sm0_holds_then_segments() {
        let data: Vec<u8> = (0..=255u8).collect();
        let mut t = Run::new(SdoTransfer::download(1, 0x2100, 2), None, &data);
        let (_, m) = written(&t);
        // Initiate: 0x21, size 256, then 112 bytes (128 − 6 − 2 − 8).
        assert_eq!(&m[8..16], &[0x21, 0x00, 0x21, 0x02, 0, 1, 0, 0]);
        assert_eq!(u16::from_le_bytes([m[0], m[1]]), 2 + 8 + 112);
        assert_eq!(&m[16..128], &data[..112]);
        exchange(
            &mut t,
            &answer(COE_SDO_RESPONSE, &[0x60, 0x00, 0x21, 0x02, 0, 0, 0, 0]),
            1,
        );
        // Segments of 119 bytes (128 − 9): the first not last, toggle 0.
        let (_, m) = written(&t);
        assert_eq!(m[8], 0x00);
        assert_eq!(&m[9..128], &data[112..231]);
        exchange(
            &mut t,
            &answer(COE_SDO_RESPONSE, &[0x20, 0, 0, 0, 0, 0, 0, 0]),
            2,
        );
        // The rest, 25 bytes, last, toggle 1.
        let (_, m) = written(&t);
        assert_eq!(m[8], 0x11);
        assert_eq!(u16::from_le_bytes([m[0], m[1]]), 3 + 25);
        assert_eq!(&m[9..34], &data[231..]);
        exchange(
            &mut t,
            &answer(COE_SDO_RESPONSE, &[0x30, 0, 0, 0, 0, 0, 0, 0]),
            3,
        );
        assert_eq!(t.outcome(), Some(Ok(vec![])));
    }

    #[test]
    fn aborts_emergencies_and_mailbox_errors() {
        let req = SdoTransfer::upload(2, 0x2000, 0);
        let mut t = Run::new(req, None, &[]);
        // An emergency in between is not the answer: wait on.
        exchange(
            &mut t,
            &answer(COE_EMERGENCY, &[0x10, 0x81, 0x11, 0, 0, 0, 0, 0]),
            1,
        );
        assert_eq!(t.outcome(), None);
        assert_eq!(
            t.next_access(),
            Some(MailboxAccess::ReadStatus { at: 0x080D })
        );
        t.on_answer(MailboxAnswer::Status(SM_STATUS_MAILBOX_FULL), &[], 2);
        let abort = answer(
            COE_SDO_REQUEST,
            &[0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x02, 0x06],
        );
        t.on_answer(MailboxAnswer::Read, &abort, 2);
        assert_eq!(
            t.outcome(),
            Some(Err(SdoError::Aborted {
                drive: 2,
                index: 0x2000,
                sub: 0,
                code: AbortCode::OBJECT_DOES_NOT_EXIST
            }))
        );
        // A slave without CoE answers with a mailbox error reply.
        let mut t = Run::new(req, None, &[]);
        let mut error = vec![0u8; ANSWER_KEEP];
        error[0] = 4;
        error[5] = MAILBOX_TYPE_ERROR;
        exchange(&mut t, &error, 1);
        assert!(
            matches!(t.outcome(), Some(Err(SdoError::Protocol { what, .. })) if what.contains("mailbox error")),
            "{:?}",
            t.outcome()
        );
    }

    #[test]
    fn a_late_answer_to_a_transfer_that_timed_out_is_passed_over() {
        let mut up = SdoTransfer::upload(0, 0x6060, 0);
        up.timeout_ns = 10;
        let mut t = Run::new(up, None, &[]);
        t.on_answer(MailboxAnswer::Written, &[], 20);
        assert!(matches!(t.outcome(), Some(Err(SdoError::TimedOut { .. }))));
        assert!(t.t.left_unanswered(), "its request was out");
        // The next transfer, a download to the same object, first meets the late upload
        // answer: passed over, then its own answer.
        let req = SdoTransfer::download(0, 0x6060, 0);
        let mut t = Run::new(req, Some(t.t.counter()), &[9]);
        t.t = t.t.after_unanswered(true);
        let late = answer(COE_SDO_RESPONSE, &[0x4F, 0x60, 0x60, 0x00, 8, 0, 0, 0]);
        exchange(&mut t, &late, 1);
        assert_eq!(t.outcome(), None, "not ours: waiting on");
        exchange_read(
            &mut t,
            &answer(COE_SDO_RESPONSE, &[0x60, 0x60, 0x60, 0, 0, 0, 0, 0]),
            2,
        );
        assert_eq!(t.outcome(), Some(Ok(vec![])));
        assert!(!t.t.left_unanswered());
        // Without a transfer left unanswered, the same answer is a protocol error.
        let mut t = Run::new(req, Some(3), &[9]);
        exchange(&mut t, &late, 1);
        assert!(matches!(t.outcome(), Some(Err(SdoError::Protocol { .. }))));
    }

    #[test]
    fn a_silent_slave_times_out_with_the_time_waited() {
        let mut req = SdoTransfer::upload(0, 0x1018, 1);
        req.timeout_ns = 50_000_000;
        let mut t = Run::new(req, None, &[]);
        t.t = CoeSdo::new(MAILBOX, req, None, 1_000);
        t.on_answer(MailboxAnswer::Written, &[], 1_000_000);
        let mut now = 1_000_000;
        while t.outcome().is_none() {
            now += 1_000_000;
            t.on_answer(MailboxAnswer::Status(0), &[], now);
        }
        assert_eq!(
            t.outcome(),
            Some(Err(SdoError::TimedOut {
                drive: 0,
                index: 0x1018,
                sub: 1,
                waited_ms: 50
            }))
        );
        assert_eq!(t.next_access(), None);
    }

    /// A segmented upload of more than the initiate carries, each answer 40 ms after its
    /// request and the slave given 50 ms: it takes far longer than 50 ms in all and
    /// completes, every byte in place (the timeout is the slave's silence, not the
    /// transfer's length); an answer 60 ms late times it out.
    #[test]
    fn a_long_upload_is_timed_answer_by_answer() {
        let object: Vec<u8> = (0..600u32).map(|i| (i * 7 + i / 256) as u8).collect();
        for late_ms in [40, 60] {
            let mut req = SdoTransfer::upload(0, 0x2F00, 0);
            req.timeout_ns = 50_000_000;
            let mut t = Run::new(req, None, &[]);
            let mut now = 0;
            let mut sent = 0;
            let mut toggle = false;
            while t.outcome().is_none() {
                now += late_ms * 1_000_000;
                t.on_answer(MailboxAnswer::Written, &[], now);
                if t.outcome().is_some() {
                    break;
                }
                let reply = if sent == 0 {
                    let mut init = vec![0x41, 0x00, 0x2F, 0x00];
                    init.extend((object.len() as u32).to_le_bytes());
                    init.extend(&object[..112]);
                    sent = 112;
                    answer(COE_SDO_RESPONSE, &init)
                } else {
                    let chunk = (object.len() - sent).min(119);
                    let last = sent + chunk == object.len();
                    let mut seg = vec![(u8::from(toggle) << 4) | u8::from(last)];
                    seg.extend(&object[sent..sent + chunk]);
                    sent += chunk;
                    toggle = !toggle;
                    answer(COE_SDO_RESPONSE, &seg)
                };
                exchange_read(&mut t, &reply, now);
            }
            if late_ms == 40 {
                assert!(now > 200_000_000, "{now} ns in all");
                assert_eq!(t.outcome(), Some(Ok(object.clone())));
            } else {
                assert!(
                    matches!(
                        t.outcome(),
                        Some(Err(SdoError::TimedOut { waited_ms: 60, .. }))
                    ),
                    "{:?}",
                    t.outcome()
                );
            }
        }
    }

    #[test]
    fn an_upload_larger_than_its_buffer_is_aborted_at_the_slave() {
        let mut t = Run::new(SdoTransfer::upload(0, 0x1008, 0), None, &[]);
        exchange(
            &mut t,
            &answer(
                COE_SDO_RESPONSE,
                &[0x41, 0x08, 0x10, 0x00, 0x2C, 0x01, 0, 0],
            ),
            1,
        );
        let (_, m) = written(&t);
        assert_eq!(&m[8..16], &[0x80, 0x08, 0x10, 0x00, 0x05, 0x00, 0x04, 0x05]);
        t.on_answer(MailboxAnswer::Written, &[], 2);
        assert_eq!(
            t.outcome(),
            Some(Err(SdoError::TooLarge {
                drive: 0,
                index: 0x1008,
                sub: 0,
                size: crate::runtime::sdo::ObjectBytes(Some(300)),
                max: 256
            }))
        );
    }
}
