//! The node's link protocol: the messages that cross USART1 between host and node, defined once for
//! both sides, and their framing.
//!
//! A frame is one message serialised with postcard, COBS-encoded, and terminated by a single `0x00`
//! byte (COBS guarantees the encoded body holds no zero). Both ends send each frame with a `0x00`
//! in front of it as well ([`encode_sync`]): a receiver that joined the stream mid-frame (a
//! serial port opened on a running node) drops the bytes up to its first `0x00`, and with the
//! leading zero that is never more than the tail of one frame. A frame must decode to exactly
//! one message: bytes left after it make it malformed, so the tail of a frame that happens to
//! begin like another message is refused, not taken for that message. Every message type is a
//! plain serde enum; postcard encodes a variant as its index (varint) followed by its fields,
//! integers as varints, floats as little-endian IEEE 754. The protocol version is [`PROTOCOL_VERSION`]; the node states
//! it in every [`Status`], and new variants are only ever appended so that old bytes keep decoding.
//!
//! No-panic contract: [`FrameDecoder::push`] accepts any byte string. Malformed frames (bad COBS,
//! bad postcard, unknown variant, frames longer than the decoder's buffer) come out as a typed
//! [`FrameError`] and the decoder resynchronises at the next `0x00`.

use heapless::Vec;
use serde::{Deserialize, Serialize};

/// Version of this protocol; bumped when a message changes incompatibly.
///
/// Version 2: [`Status`] gained `reset_cause` and `trigger_mismatch`; [`HostMsg::SetRate`],
/// [`NodeMsg::RateSet`] and [`NodeMsg::Refused`] were added.
///
/// Version 3: [`NodeMsg::Samples`] carries `first`, the node's sample counter of its first set
/// (sets lost before the link show as a jump); [`RecordStatus::InUse`] carries the record's CRC;
/// [`Status`] carries the [`Output`] mode; [`HostMsg::GetInfo`] / [`NodeMsg::Info`] (who the node
/// is), [`HostMsg::SetOutput`] / [`NodeMsg::OutputSet`] (raw or calibrated streaming) and
/// [`Block::Raw`] were added.
///
/// Version 4: [`NodeMsg::Samples`] carries `temp`, the temperature read with the block and the
/// one a thermal record was applied at ([`BlockTemp`]); [`HostMsg::Replay`] carries each set's
/// temperature ([`ReplayTemp`]) and [`NodeMsg::Replayed`] the block's [`BlockTemp`];
/// [`RecordFault::NoTempInput`] was added.
pub const PROTOCOL_VERSION: u8 = 4;

/// The temperature of a block of live samples.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockTemp {
    /// Mean of the temperature input over the block's sets, °C (the front end's channel on the
    /// emulated bench, the MCU's sensor on the board).
    pub mean_c: f32,
    /// With a thermal record in force and calibrated output: the filtered temperature the
    /// calibration of the block's last set was evaluated at, °C.
    pub applied_c: Option<f32>,
    /// The calibration was applied outside the record's calibrated temperature range (or could
    /// not be evaluated there): the output is extrapolated.
    pub out_of_range: bool,
}

/// Most sample sets one message carries (live samples, replay requests and answers).
pub const MAX_BLOCK: usize = 16;

/// Size of every frame buffer: at least the longest encoded frame of any message in this module,
/// the terminating zero included ([`MAX_NODE_FRAME`], [`MAX_REQUEST_FRAME`]).
pub const MAX_FRAME: usize = 256;

/// Longest frame of any [`NodeMsg`], with the leading zero the node puts in front of it
/// ([`encode_sync`]): [`NodeMsg::Samples`] with a block of [`MAX_BLOCK`] f32 triads and its
/// temperature, 1 (variant) + 5 (seq varint) + 5 (first varint) + 1 (block variant) + 1
/// (length) + 16·12 + 11 (`Some` [`BlockTemp`]) = 216 bytes, + 1 COBS + 1 terminator + 1
/// leading zero (tested).
pub const MAX_NODE_FRAME: usize = 219;
const _: () = assert!(MAX_NODE_FRAME <= MAX_FRAME && MAX_REQUEST_FRAME <= MAX_FRAME);

/// A raw 16-bit code set: channels x, y, z.
pub type Codes = [u16; 3];

/// Lowest live sampling rate per channel the node accepts ([`HostMsg::SetRate`]), Hz.
///
/// Not an ADC limit (the node's ADC erratum workaround holds at any rate, see
/// `firmware/README.md`): at 100 Hz a block of [`MAX_BLOCK`] sets leaves the node every 160 ms, so a
/// monitor still sees several blocks between two status reports; slower rates belong to another
/// kind of logger.
pub const RATE_MIN_HZ: u32 = 100;
/// Highest live sampling rate per channel the node accepts, Hz.
///
/// Two limits, both with margin: one ADC scan (a discarded conversion and three channels, each
/// oversampled 16×, 247.5-cycle sampling at 80 MHz) takes 159 µs, so the ADC alone would allow
/// 6.3 kHz; and a block of 16 calibrated sets is a frame of at most [`MAX_NODE_FRAME`] = 219
/// bytes, so 4 kHz is 54.8 kB/s, 59 % of USART1 at 921600 baud (92.16 kB/s), leaving the rest for
/// status reports and replay answers.
pub const RATE_MAX_HZ: u32 = 4000;
/// The live sampling rate the node starts with, Hz.
pub const DEFAULT_RATE_HZ: u32 = 1000;

/// Size of the node's link receive ring, bytes (the real board's USART1 DMA ring).
///
/// The link task stops reading the ring while it waits for room in its outbox (4 messages of at
/// most [`MAX_NODE_FRAME`] = 219 bytes, 2.38 ms each at 921600 baud). With live sampling at
/// [`RATE_MAX_HZ`] taking a slot every 4 ms, the wait is at most 3 transmissions, 7.1 ms, in
/// which a host sending without pause delivers 657 bytes; 2048 bytes hold 22 ms of line time,
/// 3.1× that. A host that
/// keeps to [`MAX_REQUESTS_IN_FLIGHT`] cannot overrun it however long the wait.
pub const LINK_RX_RING: usize = 2048;

/// Longest frame of any [`HostMsg`], with the single `0x00` a sender may put in front of it to
/// resynchronise the receiver: a [`HostMsg::Replay`] of [`MAX_BLOCK`] sets with their
/// temperatures is 1 (variant) + 5 (seq) + 1 (length) + 16·3·3 (u16 varints) + 1 (`Some`) +
/// 1 (`restart`) + 1 (length) + 16·4 (f32) = 218 bytes, + 1 COBS + 1 terminator + 1 leading zero
/// (tested).
pub const MAX_REQUEST_FRAME: usize = 221;

/// Requests ([`HostMsg`]) the host may send before the node has answered them (flow control).
///
/// The bytes of a request leave the node's receive ring before its answer is produced, so the
/// ring never holds more than the unanswered requests: 9 × 221 = 1989 bytes ≤
/// [`LINK_RX_RING`]. Every request is answered: `GetStatus` by a status, `Replay` by `Replayed`,
/// `SetRate` by `RateSet` or `Refused`; frames that do not decode are not answered, so a host
/// that sends one counts it as answered.
pub const MAX_REQUESTS_IN_FLIGHT: usize = LINK_RX_RING / MAX_REQUEST_FRAME;

const _: () = assert!(MAX_REQUESTS_IN_FLIGHT * MAX_REQUEST_FRAME <= LINK_RX_RING);
const _: () = assert!(MAX_REQUESTS_IN_FLIGHT >= 8, "enough requests in flight to keep the node busy");

/// What the host sends to the node.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum HostMsg {
    /// Ask for a [`NodeMsg::Status`] now.
    GetStatus,
    /// Calibrate these raw code sets with the node's own arithmetic; the node answers
    /// [`NodeMsg::Replayed`] with the same `seq`.
    Replay {
        /// Request number, echoed in the answer.
        seq: u32,
        /// Raw code sets, x, y, z.
        codes: Vec<Codes, MAX_BLOCK>,
        /// The sets' temperatures, for a record with thermal terms; `None` replays a thermal
        /// record at its reference temperature (the calibration a node applies before it has
        /// read a temperature).
        temp: Option<ReplayTemp>,
    },
    /// Set the live sampling rate per channel to `hz`; the node answers [`NodeMsg::RateSet`] with
    /// its new status, or [`NodeMsg::Refused`] when `hz` is outside
    /// [`RATE_MIN_HZ`]`..=`[`RATE_MAX_HZ`].
    SetRate {
        /// The requested rate, Hz.
        hz: u32,
    },
    /// Ask who the node is; the node answers [`NodeMsg::Info`].
    GetInfo,
    /// Stream live samples calibrated or raw; the node answers [`NodeMsg::OutputSet`] with its
    /// status (in which `output` says what it now streams).
    SetOutput(Output),
}

/// The temperatures of a [`HostMsg::Replay`]'s sets.
///
/// The node replays a thermal record as it applies it live, with a
/// [`crate::thermal::ThermalTracker`] fed each set's temperature in order; its replay tracker is
/// its own (the live stream's is untouched), started afresh by a request with `restart` and kept
/// from one request to the next otherwise, so a host that sends a run's blocks in order, the first
/// with `restart`, reproduces the node's output bit for bit with a tracker of its own.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReplayTemp {
    /// Start a fresh tracker with this request (the first request of a replay run).
    pub restart: bool,
    /// Temperature of each set, °C, one per code set (the node calibrates only the sets that have
    /// one).
    pub temp_c: Vec<f32, MAX_BLOCK>,
}

/// What the node streams as live samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Output {
    /// Calibrated acceleration ([`Block::Calibrated`] or [`Block::CalibratedFixed`]); raw codes
    /// flagged [`Block::Uncalibrated`] while the node has no valid record. The mode at boot.
    Calibrated,
    /// Raw codes ([`Block::Raw`]), whatever the record: what a recalibration records.
    Raw,
}

impl Output {
    /// The mode's name as the host tool writes it (`calibrated`, `raw`).
    pub fn name(self) -> &'static str {
        match self {
            Output::Calibrated => "calibrated",
            Output::Raw => "raw",
        }
    }
}

/// Who the node is: the answer to [`HostMsg::GetInfo`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Info {
    /// The MCU's 96-bit unique id (the QEMU board reports
    /// [`crate::contract::QEMU_DEVICE_ID`]), which a record's device id must equal.
    pub device_id: [u8; 12],
    /// The firmware's version, major, minor, patch (its Cargo package version).
    pub firmware: [u16; 3],
    /// [`PROTOCOL_VERSION`] of the node's firmware.
    pub protocol: u8,
    /// The record in force, or why there is none.
    pub record: RecordStatus,
    /// Sampling rate per channel in force, Hz.
    pub rate_hz: u32,
    /// Sample sets lost since boot.
    pub overruns: u32,
    /// Why the node last reset.
    pub reset_cause: ResetCause,
    /// What the node streams now.
    pub output: Output,
}

/// Whether the node accepts `hz` as its sampling rate ([`HostMsg::SetRate`]).
pub fn check_rate(hz: u32) -> Result<(), Refusal> {
    if (RATE_MIN_HZ..=RATE_MAX_HZ).contains(&hz) {
        Ok(())
    } else {
        Err(Refusal::RateOutOfRange { requested_hz: hz, min_hz: RATE_MIN_HZ, max_hz: RATE_MAX_HZ })
    }
}

/// A block of sample sets in one of the node's output forms.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Block {
    /// Calibrated acceleration `[ax, ay, az]` in m/s², computed in f32.
    Calibrated(Vec<[f32; 3], MAX_BLOCK>),
    /// Calibrated acceleration in fixed point, m/s²·2¹⁶ (the `fixed-point` firmware build).
    CalibratedFixed(Vec<[i32; 3], MAX_BLOCK>),
    /// Raw codes, NOT calibrated: the node has no valid record.
    Uncalibrated(Vec<Codes, MAX_BLOCK>),
    /// Raw codes streamed on request ([`Output::Raw`]), whatever the record.
    Raw(Vec<Codes, MAX_BLOCK>),
}

impl Block {
    /// Number of sample sets in the block.
    pub fn len(&self) -> usize {
        match self {
            Block::Calibrated(v) => v.len(),
            Block::CalibratedFixed(v) => v.len(),
            Block::Uncalibrated(v) | Block::Raw(v) => v.len(),
        }
    }

    /// True when the block holds no sample set.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Why the node runs without a calibration record.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum RecordFault {
    /// Neither record slot holds a committed slot image (e.g. erased flash, a write cut before its
    /// commit, or a slot left unreadable by a flash ECC error).
    NoSlot,
    /// The active slot's record does not parse; the value is the [`crate::record::RecordError`]
    /// as named by [`record_error_code`].
    BadRecord(u8),
    /// The record was made for another device (MCU unique id mismatch).
    WrongDevice,
    /// The record is not model 4 for three channels.
    NotModel4,
    /// The record's sensitivity matrix cannot be inverted (or does not fit fixed point).
    Singular,
    /// The record's thermal terms read a temperature input the node's board does not have
    /// ([`crate::boot::TempInputs`]: the real board has the MCU's sensor, the QEMU board the
    /// front end's channel).
    NoTempInput,
}

/// The calibration record the node uses, or why it has none.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum RecordStatus {
    /// A valid record is applied to every sample set.
    InUse {
        /// Record slot it was read from (0 or 1).
        slot: u8,
        /// The slot's write sequence number.
        sequence: u32,
        /// The record's creation time, seconds since the Unix epoch.
        created_unix_s: u64,
        /// The record's CRC-32 (its last four bytes, [`crate::record`]).
        crc: u32,
    },
    /// No valid record: the node streams raw codes flagged uncalibrated.
    Missing(RecordFault),
}

/// The node's health report.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Status {
    /// [`PROTOCOL_VERSION`] of the node's firmware.
    pub protocol: u8,
    /// Record in use.
    pub record: RecordStatus,
    /// Sample sets lost because the output could not keep up (DMA ring overruns), since boot.
    pub overruns: u32,
    /// Sample sets acquired since boot.
    pub sample_sets: u32,
    /// Sampling rate per channel, Hz (0 on a board whose samples arrive over the link).
    pub rate_hz: u32,
    /// Host frames the node could not decode, since boot.
    pub bad_frames: u32,
    /// Why the node last reset (RCC_CSR at boot).
    pub reset_cause: ResetCause,
    /// The read-back of the ADC trigger configuration (at boot and after each rate change) did not
    /// match what the node programmed; the defmt log names the fields. Always false on a board
    /// without an ADC (QEMU).
    pub trigger_mismatch: bool,
    /// What the node streams now.
    pub output: Output,
}

/// Why the node last reset, from the reset flags of RCC_CSR (RM0351 §6.4.29, bits 24..=31).
///
/// Several flags can be set at once: every reset drives the NRST pin low, so PINRSTF accompanies
/// the others, and a power-on sets BORRSTF and PINRSTF. The cause is the most specific flag, in
/// the order of the variants below (Pin last); the node clears the flags (RMVF) after reading
/// them, so each boot sees only its own reset's flags.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResetCause {
    /// No reset flag set (flags cleared and no reset recorded since, or not readable).
    Unknown,
    /// Illegal Stop/Standby/Shutdown entry with the nRST_STOP/STDBY/SHDW option clear (LPWRRSTF).
    LowPower,
    /// The window watchdog (WWDGRSTF).
    WindowWatchdog,
    /// The independent watchdog (IWDGRSTF): the node's main loop stopped feeding it.
    IndependentWatchdog,
    /// A software reset (SFTRSTF): the node's panic handler, or a debugger.
    Software,
    /// A firewall violation (FWRSTF).
    Firewall,
    /// An option byte load (OBLRSTF).
    OptionByte,
    /// Power-on or brown-out (BORRSTF).
    PowerOn,
    /// The NRST pin alone (PINRSTF): the reset button or the debug probe.
    Pin,
}

impl ResetCause {
    /// The cause recorded in an RCC_CSR value (only bits 24..=31 are looked at).
    pub fn from_rcc_csr(csr: u32) -> ResetCause {
        const FLAGS: [(u32, ResetCause); 8] = [
            (31, ResetCause::LowPower),
            (30, ResetCause::WindowWatchdog),
            (29, ResetCause::IndependentWatchdog),
            (28, ResetCause::Software),
            (24, ResetCause::Firewall),
            (25, ResetCause::OptionByte),
            (27, ResetCause::PowerOn),
            (26, ResetCause::Pin),
        ];
        FLAGS.iter().find(|(bit, _)| csr & (1 << bit) != 0).map_or(ResetCause::Unknown, |&(_, c)| c)
    }
}

impl core::fmt::Display for ResetCause {
    /// The variant's name, then what it means.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ResetCause::Unknown => "Unknown: no reset flag was set",
            ResetCause::LowPower => "LowPower: illegal low-power mode entry",
            ResetCause::WindowWatchdog => "WindowWatchdog: window watchdog reset",
            ResetCause::IndependentWatchdog => "IndependentWatchdog: the watchdog was not fed in time",
            ResetCause::Software => "Software: software reset (panic or debugger)",
            ResetCause::Firewall => "Firewall: firewall reset",
            ResetCause::OptionByte => "OptionByte: option byte load reset",
            ResetCause::PowerOn => "PowerOn: power-on or brown-out reset",
            ResetCause::Pin => "Pin: reset pin (button or debug probe)",
        })
    }
}

/// Why the node refused a host request.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Refusal {
    /// [`HostMsg::SetRate`] outside the accepted range; the rate is unchanged.
    RateOutOfRange {
        /// The rate asked for, Hz.
        requested_hz: u32,
        /// Lowest accepted rate, Hz ([`RATE_MIN_HZ`] of the node's build).
        min_hz: u32,
        /// Highest accepted rate, Hz ([`RATE_MAX_HZ`] of the node's build).
        max_hz: u32,
    },
}

impl core::fmt::Display for Refusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Refusal::RateOutOfRange { requested_hz, min_hz, max_hz } => write!(
                f,
                "RateOutOfRange: sampling rate {requested_hz} Hz refused, the node accepts {min_hz}..={max_hz} Hz"
            ),
        }
    }
}

/// What the node sends to the host.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum NodeMsg {
    /// Health report, sent periodically and on [`HostMsg::GetStatus`].
    Status(Status),
    /// Live samples, `seq` counting blocks since boot.
    Samples {
        /// Block number since boot (gaps mean blocks the link could not take).
        seq: u32,
        /// The node's sample counter of the block's first set: every set the sampler produced
        /// since boot, lost ones included, so `first / rate_hz` is the set's time and a jump
        /// between consecutive blocks is the number of sets lost (counted in
        /// [`Status::overruns`]).
        first: u32,
        /// The sample sets.
        data: Block,
        /// The block's temperature, when the node reads one.
        temp: Option<BlockTemp>,
    },
    /// The answer to [`HostMsg::Replay`] with the same `seq`.
    Replayed {
        /// The request's number.
        seq: u32,
        /// The request's code sets, calibrated (or flagged uncalibrated).
        data: Block,
        /// With the request's temperatures: the block's temperature as in live samples
        /// ([`BlockTemp`]; `applied_c` from the replay tracker when a thermal record is in force).
        temp: Option<BlockTemp>,
    },
    /// The answer to an accepted [`HostMsg::SetRate`]: the status with the new rate.
    RateSet(Status),
    /// The answer to a request the node refused, and why.
    Refused(Refusal),
    /// The answer to [`HostMsg::GetInfo`].
    Info(Info),
    /// The answer to [`HostMsg::SetOutput`]: the status with the new output mode.
    OutputSet(Status),
}

/// Why a frame could not be encoded or decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// The frame is longer than the decoder's buffer (or the encode buffer is too small).
    TooLong,
    /// The COBS or postcard content is invalid (unknown variant, truncated field, bad varint...).
    Malformed,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FrameError::TooLong => "frame too long",
            FrameError::Malformed => "malformed frame",
        })
    }
}

#[cfg(feature = "std")]
impl std::error::Error for FrameError {}

impl core::fmt::Display for RecordFault {
    /// The variant's name (so that logs and scripts can match it), then what it means.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            RecordFault::NoSlot => {
                f.write_str("NoSlot: no record slot holds a complete record (erased flash or an unfinished write)")
            }
            RecordFault::BadRecord(code) => {
                let i = (code as usize).wrapping_sub(1);
                match (RECORD_ERROR_NAMES.get(i), RECORD_ERROR_WORDS.get(i)) {
                    (Some(name), Some(words)) => {
                        write!(f, "BadRecord({name}): the record in force is invalid: {words}")
                    }
                    _ => write!(f, "BadRecord({code}): the record in force is invalid (reason code unknown to this host)"),
                }
            }
            RecordFault::WrongDevice => {
                f.write_str("WrongDevice: the record was made for another device (MCU unique id mismatch)")
            }
            RecordFault::NotModel4 => f.write_str(
                "NotModel4: the node applies model 4 (terms 1,ax,ay,az) for three channels only, the record holds another model",
            ),
            RecordFault::Singular => f.write_str(
                "Singular: the record's sensitivity matrix cannot be inverted (or does not fit the fixed-point build)",
            ),
            RecordFault::NoTempInput => f.write_str(
                "NoTempInput: the record's thermal terms read a temperature input this board does not have \
                 (the real board reads the MCU's sensor, the QEMU board the front end's channel)",
            ),
        }
    }
}

/// Names of the [`crate::record::RecordError`] variants by their [`record_error_code`] (code 1
/// first), as [`RecordFault::BadRecord`] is displayed.
pub const RECORD_ERROR_NAMES: [&str; 10] = [
    "Truncated",
    "BadMagic",
    "UnsupportedVersion",
    "BadLength",
    "BadChannelCount",
    "BadTerms",
    "BadCrc",
    "NonFinite",
    "BufferTooSmall",
    "BadThermal",
];

/// What each record error means, in the order of [`RECORD_ERROR_NAMES`]. (The code does not
/// carry the error's value: an unsupported version is named, not its number.)
const RECORD_ERROR_WORDS: [&str; 10] = [
    "it is truncated",
    "it is not a calibration record (bad magic)",
    "its format version is not 1 or 2, the ones the node reads",
    "its length field is inconsistent",
    "its channel count is out of range",
    "its term list is invalid",
    "its CRC does not match",
    "it holds a non-finite coefficient",
    "buffer too small",
    "its gravity or temperature fields are inconsistent with its terms",
];

const _: () = assert!(crate::record::FORMAT_VERSION == 2, "update RECORD_ERROR_WORDS");

/// The variant name of a record error code (see [`record_error_code`]), or `None` for a code this
/// build does not know.
pub fn record_error_name(code: u8) -> Option<&'static str> {
    RECORD_ERROR_NAMES.get((code as usize).wrapping_sub(1)).copied()
}

/// A stable one-byte code for a record error, for [`RecordFault::BadRecord`].
pub fn record_error_code(e: crate::record::RecordError) -> u8 {
    use crate::record::RecordError as E;
    match e {
        E::Truncated => 1,
        E::BadMagic => 2,
        E::UnsupportedVersion(_) => 3,
        E::BadLength => 4,
        E::BadChannelCount => 5,
        E::BadTerms => 6,
        E::BadCrc => 7,
        E::NonFinite => 8,
        E::BufferTooSmall => 9,
        E::BadThermal => 10,
    }
}

/// Serialises `msg` into one frame (COBS body and terminating zero) at the start of `buf` and
/// returns the frame.
pub fn encode<'a, T: Serialize>(msg: &T, buf: &'a mut [u8]) -> Result<&'a [u8], FrameError> {
    match postcard::to_slice_cobs(msg, buf) {
        Ok(frame) => Ok(frame),
        Err(_) => Err(FrameError::TooLong),
    }
}

/// [`encode`] with a `0x00` in front of the frame, as both ends of the node link send: the zero
/// ends whatever a receiver holds (the tail of a frame it joined mid-way, or noise), so the
/// frame after it is read whole. Receivers skip the empty frame it makes.
pub fn encode_sync<'a, T: Serialize>(msg: &T, buf: &'a mut [u8]) -> Result<&'a [u8], FrameError> {
    let (zero, body) = buf.split_first_mut().ok_or(FrameError::TooLong)?;
    *zero = 0;
    let n = encode(msg, body)?.len();
    Ok(&buf[..n + 1])
}

/// Decodes one frame's COBS body (the bytes between two zeros) in place into exactly one
/// message: bad COBS, bad postcard and bytes left over after the message are all
/// [`FrameError::Malformed`].
fn decode_body<T: for<'de> Deserialize<'de>>(body: &mut [u8]) -> Result<T, FrameError> {
    let n = cobs::decode_in_place(body).map_err(|_| FrameError::Malformed)?;
    match postcard::take_from_bytes::<T>(&body[..n]) {
        Ok((msg, [])) => Ok(msg),
        _ => Err(FrameError::Malformed),
    }
}

/// Accumulates link bytes into frames and decodes them; `N` is the longest accepted frame.
pub struct FrameDecoder<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflow: bool,
}

impl<const N: usize> Default for FrameDecoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FrameDecoder<N> {
    /// An empty decoder.
    pub const fn new() -> Self {
        FrameDecoder { buf: [0; N], len: 0, overflow: false }
    }

    /// Feeds bytes; calls `on_frame` once per complete frame with the decoded message or why it
    /// failed. Empty frames (two zeros in a row) are skipped silently: a sender may emit a lone
    /// zero to resynchronise the receiver.
    pub fn push<T, F>(&mut self, bytes: &[u8], mut on_frame: F)
    where
        T: for<'de> Deserialize<'de>,
        F: FnMut(Result<T, FrameError>),
    {
        for &b in bytes {
            if b != 0 {
                if self.len < N {
                    self.buf[self.len] = b;
                    self.len += 1;
                } else {
                    self.overflow = true;
                }
                continue;
            }
            let (len, overflow) = (self.len, self.overflow);
            self.len = 0;
            self.overflow = false;
            if overflow {
                on_frame(Err(FrameError::TooLong));
            } else if len > 0 {
                on_frame(decode_body(&mut self.buf[..len]));
            }
        }
    }
}

#[cfg(test)]
mod tests;
