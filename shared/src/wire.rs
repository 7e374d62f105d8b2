//! The node's link protocol: the messages that cross USART1 between host and node, defined once for
//! both sides, and their framing.
//!
//! A frame is one message serialised with postcard, COBS-encoded, and terminated by a single `0x00`
//! byte (COBS guarantees the encoded body holds no zero). Every message type is a plain serde enum;
//! postcard encodes a variant as its index (varint) followed by its fields, integers as varints,
//! floats as little-endian IEEE 754. The protocol version is [`PROTOCOL_VERSION`]; the node states
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

/// Longest frame of any [`NodeMsg`]: [`NodeMsg::Samples`] with a block of [`MAX_BLOCK`] f32
/// triads and its temperature, 1 (variant) + 5 (seq varint) + 5 (first varint) + 1 (block
/// variant) + 1 (length) + 16·12 + 11 (`Some` [`BlockTemp`]) = 216 bytes, + 1 COBS + 1
/// terminator (tested).
pub const MAX_NODE_FRAME: usize = 218;
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
/// 6.3 kHz; and a block of 16 calibrated sets is a frame of at most [`MAX_NODE_FRAME`] = 218
/// bytes, so 4 kHz is 54.5 kB/s, 59 % of USART1 at 921600 baud (92.16 kB/s), leaving the rest for
/// status reports and replay answers.
pub const RATE_MAX_HZ: u32 = 4000;
/// The live sampling rate the node starts with, Hz.
pub const DEFAULT_RATE_HZ: u32 = 1000;

/// Size of the node's link receive ring, bytes (the real board's USART1 DMA ring).
///
/// The link task stops reading the ring while it waits for room in its outbox (4 messages of at
/// most [`MAX_NODE_FRAME`] = 218 bytes, 2.37 ms each at 921600 baud). With live sampling at
/// [`RATE_MAX_HZ`] taking a slot every 4 ms, the wait is at most 3 transmissions, 7.1 ms, in
/// which a host sending without pause delivers 654 bytes; 2048 bytes hold 22 ms of line time,
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
                on_frame(
                    postcard::from_bytes_cobs::<T>(&mut self.buf[..len]).map_err(|_| FrameError::Malformed),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode_all<T: for<'de> Deserialize<'de>>(bytes: &[u8]) -> std::vec::Vec<Result<T, FrameError>> {
        let mut d = FrameDecoder::<MAX_FRAME>::new();
        let mut out = std::vec::Vec::new();
        d.push(bytes, |m| out.push(m));
        out
    }

    fn codes(v: &[Codes]) -> Vec<Codes, MAX_BLOCK> {
        Vec::from_slice(v).unwrap()
    }

    #[test]
    fn get_status_literal_bytes() {
        // postcard: variant 0 → [0x00]; COBS: [0x01, 0x01]; terminator 0x00.
        let mut buf = [0u8; MAX_FRAME];
        assert_eq!(encode(&HostMsg::GetStatus, &mut buf).unwrap(), &[0x01, 0x01, 0x00]);
        assert_eq!(decode_all::<HostMsg>(&[0x01, 0x01, 0x00]), vec![Ok(HostMsg::GetStatus)]);
    }

    #[test]
    fn replay_literal_bytes() {
        // Replay = variant 1, seq 300 = varint [0xac, 0x02], 2 sets, u16 varints:
        // 1 → [0x01], 2 → [0x02], 0x8000 → [0x80, 0x80, 0x02], then 0, 65535 → [0xff, 0xff, 0x03], 7.
        let raw: &[u8] =
            &[0x01, 0xac, 0x02, 0x02, 0x01, 0x02, 0x80, 0x80, 0x02, 0x00, 0xff, 0xff, 0x03, 0x07, 0x00];
        let msg = HostMsg::Replay { seq: 300, codes: codes(&[[1, 2, 0x8000], [0, 65535, 7]]), temp: None };
        assert_eq!(postcard::to_slice(&msg, &mut [0u8; 64]).unwrap(), raw);
        // (then `None` temperatures: [0x00])
        // COBS: the zeros at offsets 9 and 14 split the body into 9 + 4 + 0 non-zero bytes.
        let framed: &[u8] = &[
            0x0a, 0x01, 0xac, 0x02, 0x02, 0x01, 0x02, 0x80, 0x80, 0x02, 0x05, 0xff, 0xff, 0x03, 0x07, 0x01,
            0x00,
        ];
        let mut buf = [0u8; MAX_FRAME];
        assert_eq!(encode(&msg, &mut buf).unwrap(), framed);
        assert_eq!(decode_all::<HostMsg>(framed), vec![Ok(msg)]);
        // With temperatures: Some = [0x01], restart = [0x01], 1 temperature, f32 LE 25.5.
        let temp = ReplayTemp { restart: true, temp_c: Vec::from_slice(&[25.5]).unwrap() };
        let msg = HostMsg::Replay { seq: 1, codes: codes(&[[1, 2, 3]]), temp: Some(temp) };
        let raw: &[u8] = &[0x01, 0x01, 0x01, 0x01, 0x02, 0x03, 0x01, 0x01, 0x01, 0x00, 0x00, 0xcc, 0x41];
        assert_eq!(postcard::to_slice(&msg, &mut [0u8; 64]).unwrap(), raw);
        let frame = encode(&msg, &mut buf).unwrap().to_vec();
        assert_eq!(decode_all::<HostMsg>(&frame), vec![Ok(msg)]);
    }

    #[test]
    fn replayed_answer_literal_bytes() {
        // Replayed = variant 2, seq 5, Calibrated = variant 0, 1 set of f32 LE: 1.0, -2.5, 0.0.
        // Then the temperature: None = [0x00].
        let msg = NodeMsg::Replayed {
            seq: 5,
            data: Block::Calibrated(Vec::from_slice(&[[1.0, -2.5, 0.0]]).unwrap()),
            temp: None,
        };
        let raw: &[u8] = &[
            0x02, 0x05, 0x00, 0x01, 0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x20, 0xc0, 0x00, 0x00, 0x00, 0x00,
            0x00,
        ];
        assert_eq!(postcard::to_slice(&msg, &mut [0u8; 64]).unwrap(), raw);
        let mut buf = [0u8; MAX_FRAME];
        let frame = encode(&msg, &mut buf).unwrap().to_vec();
        assert_eq!(decode_all::<NodeMsg>(&frame), vec![Ok(msg)]);
    }

    #[test]
    fn status_round_trip_and_largest_message_fits() {
        let st = NodeMsg::Status(Status {
            protocol: PROTOCOL_VERSION,
            record: RecordStatus::InUse {
                slot: 1,
                sequence: u32::MAX,
                created_unix_s: u64::MAX,
                crc: u32::MAX,
            },
            overruns: u32::MAX,
            sample_sets: u32::MAX,
            rate_hz: 1000,
            bad_frames: 3,
            reset_cause: ResetCause::IndependentWatchdog,
            trigger_mismatch: true,
            output: Output::Raw,
        });
        let big = NodeMsg::Samples {
            seq: u32::MAX,
            first: u32::MAX,
            data: Block::Calibrated(Vec::from_slice(&[[f32::MAX; 3]; MAX_BLOCK]).unwrap()),
            temp: Some(BlockTemp { mean_c: f32::MAX, applied_c: Some(f32::MAX), out_of_range: true }),
        };
        let info = NodeMsg::Info(Info {
            device_id: [0xff; 12],
            firmware: [u16::MAX; 3],
            protocol: PROTOCOL_VERSION,
            record: RecordStatus::InUse {
                slot: 1,
                sequence: u32::MAX,
                created_unix_s: u64::MAX,
                crc: u32::MAX,
            },
            rate_hz: u32::MAX,
            overruns: u32::MAX,
            reset_cause: ResetCause::Pin,
            output: Output::Calibrated,
        });
        let mut buf = [0u8; MAX_FRAME];
        assert_eq!(encode(&big, &mut buf).unwrap().len(), MAX_NODE_FRAME, "the largest node message");
        for m in [st, big, info] {
            let frame = encode(&m, &mut buf).unwrap().to_vec();
            assert!(frame.len() <= MAX_NODE_FRAME);
            assert_eq!(decode_all::<NodeMsg>(&frame), vec![Ok(m)]);
        }
    }

    #[test]
    fn set_rate_and_its_answers_literal_bytes() {
        // SetRate = variant 2, hz 4000 = varint [0xa0, 0x1f].
        let mut buf = [0u8; MAX_FRAME];
        assert_eq!(
            postcard::to_slice(&HostMsg::SetRate { hz: 4000 }, &mut [0u8; 8]).unwrap(),
            &[0x02, 0xa0, 0x1f]
        );
        let framed: &[u8] = &[0x04, 0x02, 0xa0, 0x1f, 0x00];
        assert_eq!(encode(&HostMsg::SetRate { hz: 4000 }, &mut buf).unwrap(), framed);
        // Refused = variant 4, RateOutOfRange = variant 0, 50, 100, 4000.
        let refused =
            NodeMsg::Refused(Refusal::RateOutOfRange { requested_hz: 50, min_hz: 100, max_hz: 4000 });
        assert_eq!(postcard::to_slice(&refused, &mut [0u8; 16]).unwrap(), &[0x04, 0x00, 50, 100, 0xa0, 0x1f]);
        // RateSet = variant 3 followed by the status; the status ends with the reset cause
        // (PowerOn = variant 7) and the mismatch flag.
        let status = Status {
            protocol: PROTOCOL_VERSION,
            record: RecordStatus::Missing(RecordFault::NoSlot),
            overruns: 0,
            sample_sets: 0,
            rate_hz: 250,
            bad_frames: 0,
            reset_cause: ResetCause::PowerOn,
            trigger_mismatch: false,
            output: Output::Calibrated,
        };
        let raw: &[u8] = &[0x03, PROTOCOL_VERSION, 0x01, 0x00, 0, 0, 0xfa, 0x01, 0, 0x07, 0x00, 0x00];
        assert_eq!(postcard::to_slice(&NodeMsg::RateSet(status), &mut [0u8; 32]).unwrap(), raw);
        let frame = encode(&NodeMsg::RateSet(status), &mut buf).unwrap().to_vec();
        assert_eq!(decode_all::<NodeMsg>(&frame), vec![Ok(NodeMsg::RateSet(status))]);
    }

    #[test]
    fn info_and_output_literal_bytes() {
        // GetInfo = variant 3; SetOutput = variant 4 with Raw = variant 1.
        let mut buf = [0u8; MAX_FRAME];
        assert_eq!(encode(&HostMsg::GetInfo, &mut buf).unwrap(), &[0x02, 0x03, 0x00]);
        assert_eq!(encode(&HostMsg::SetOutput(Output::Raw), &mut buf).unwrap(), &[0x03, 0x04, 0x01, 0x00]);
        // Samples = variant 1, seq 2, first 300 = [0xac, 0x02], Raw = block variant 3, one set.
        // No temperature: Option None = 0x00.
        let msg = NodeMsg::Samples { seq: 2, first: 300, data: Block::Raw(codes(&[[1, 2, 3]])), temp: None };
        assert_eq!(
            postcard::to_slice(&msg, &mut [0u8; 32]).unwrap(),
            &[0x01, 0x02, 0xac, 0x02, 0x03, 0x01, 0x01, 0x02, 0x03, 0x00]
        );
    }

    #[test]
    fn rates_are_checked_against_the_stated_range() {
        assert_eq!(check_rate(RATE_MIN_HZ), Ok(()));
        assert_eq!(check_rate(RATE_MAX_HZ), Ok(()));
        assert_eq!(check_rate(DEFAULT_RATE_HZ), Ok(()));
        for hz in [0, RATE_MIN_HZ - 1, RATE_MAX_HZ + 1, u32::MAX] {
            let e = check_rate(hz).unwrap_err();
            assert_eq!(e, Refusal::RateOutOfRange { requested_hz: hz, min_hz: 100, max_hz: 4000 });
        }
        assert_eq!(
            std::format!("{}", check_rate(5000).unwrap_err()),
            "RateOutOfRange: sampling rate 5000 Hz refused, the node accepts 100..=4000 Hz"
        );
    }

    #[test]
    fn every_request_fits_max_request_frame_and_the_ring_holds_the_requests_in_flight() {
        let mut buf = [0u8; MAX_FRAME];
        let temp =
            || Some(ReplayTemp { restart: true, temp_c: Vec::from_slice(&[f32::MAX; MAX_BLOCK]).unwrap() });
        let largest = HostMsg::Replay { seq: u32::MAX, codes: codes(&[[65535; 3]; MAX_BLOCK]), temp: temp() };
        for m in [
            largest,
            HostMsg::GetStatus,
            HostMsg::SetRate { hz: u32::MAX },
            HostMsg::GetInfo,
            HostMsg::SetOutput(Output::Raw),
        ] {
            // +1: the leading zero a sender may add.
            let n = encode(&m, &mut buf).unwrap().len() + 1;
            assert!(n <= MAX_REQUEST_FRAME, "{m:?}: {n} bytes");
        }
        let n = encode(
            &HostMsg::Replay { seq: u32::MAX, codes: codes(&[[65535; 3]; MAX_BLOCK]), temp: temp() },
            &mut buf,
        )
        .unwrap()
        .len();
        assert_eq!(n + 1, MAX_REQUEST_FRAME, "the bound is tight");
        assert_eq!(MAX_REQUESTS_IN_FLIGHT, 9);
    }

    #[test]
    fn reset_cause_from_rcc_csr() {
        // RCC_CSR reset value after a power-on (RM0351 §6.4.29): BORRSTF | PINRSTF | MSISRANGE 6.
        assert_eq!(ResetCause::from_rcc_csr(0x0C00_0600), ResetCause::PowerOn);
        let bit = |b: u32| 1u32 << b;
        let pin = bit(26);
        assert_eq!(ResetCause::from_rcc_csr(pin), ResetCause::Pin);
        assert_eq!(ResetCause::from_rcc_csr(bit(28) | pin), ResetCause::Software);
        assert_eq!(ResetCause::from_rcc_csr(bit(29) | pin), ResetCause::IndependentWatchdog);
        assert_eq!(ResetCause::from_rcc_csr(bit(30) | pin), ResetCause::WindowWatchdog);
        assert_eq!(ResetCause::from_rcc_csr(bit(31) | pin), ResetCause::LowPower);
        assert_eq!(ResetCause::from_rcc_csr(bit(24) | pin), ResetCause::Firewall);
        assert_eq!(ResetCause::from_rcc_csr(bit(25) | pin), ResetCause::OptionByte);
        // Bits below 24 (oscillator settings, RMVF) are not reset flags.
        assert_eq!(ResetCause::from_rcc_csr(0x00FF_FFFF), ResetCause::Unknown);
        assert_eq!(ResetCause::from_rcc_csr(0), ResetCause::Unknown);
        // A watchdog reset while the power-on flags were never cleared is still the watchdog's.
        assert_eq!(ResetCause::from_rcc_csr(0x0C00_0600 | bit(29)), ResetCause::IndependentWatchdog);
        assert_eq!(
            std::format!("{}", ResetCause::IndependentWatchdog),
            "IndependentWatchdog: the watchdog was not fed in time"
        );
    }

    #[test]
    fn garbage_is_reported_and_the_decoder_resynchronises() {
        let mut bytes = vec![0x05, 0x09, 0x00]; // COBS says 4 more bytes, only 1 follows
        bytes.extend_from_slice(&[0x02, 0x63, 0x00]); // variant 99: unknown
        bytes.extend_from_slice(&[0x00, 0x00]); // empty frames: skipped
        bytes.extend_from_slice(&[0x11; MAX_FRAME + 10]); // too long
        bytes.push(0x00);
        bytes.extend_from_slice(&[0x01, 0x01, 0x00]); // GetStatus
        let got = decode_all::<HostMsg>(&bytes);
        assert_eq!(
            got,
            vec![
                Err(FrameError::Malformed),
                Err(FrameError::Malformed),
                Err(FrameError::TooLong),
                Ok(HostMsg::GetStatus)
            ]
        );
    }

    #[test]
    fn frames_split_across_pushes_decode() {
        let msg = HostMsg::Replay { seq: 9, codes: codes(&[[10, 20, 30]; 16]), temp: None };
        let mut buf = [0u8; MAX_FRAME];
        let frame = encode(&msg, &mut buf).unwrap().to_vec();
        let mut d = FrameDecoder::<MAX_FRAME>::new();
        let mut out = std::vec::Vec::new();
        for chunk in frame.chunks(3) {
            d.push(chunk, |m: Result<HostMsg, _>| out.push(m));
        }
        assert_eq!(out, vec![Ok(msg)]);
    }

    #[test]
    fn replay_with_more_than_max_block_sets_is_malformed() {
        // Variant 1, seq 0, 17 sets of [1, 1, 1]: heapless refuses the 17th.
        let mut raw = vec![0x01, 0x00, 17];
        raw.extend(std::iter::repeat_n(0x01, 17 * 3));
        let mut framed = vec![0u8; 128];
        let n = cobs_encode(&raw, &mut framed);
        framed.truncate(n);
        framed.push(0);
        assert_eq!(decode_all::<HostMsg>(&framed), vec![Err(FrameError::Malformed)]);
    }

    /// Plain COBS encoder for the tests (no zero in the input in this use).
    fn cobs_encode(src: &[u8], dst: &mut [u8]) -> usize {
        let mut out = 1;
        let mut code_at = 0;
        let mut code = 1u8;
        for &b in src {
            if b == 0 || code == 0xff {
                dst[code_at] = code;
                code_at = out;
                out += 1;
                code = 1;
                if b == 0 {
                    continue;
                }
            }
            dst[out] = b;
            out += 1;
            code += 1;
        }
        dst[code_at] = code;
        out
    }

    #[test]
    fn record_faults_are_named_in_words() {
        use crate::record::RecordError as E;
        let errors = [
            E::Truncated,
            E::BadMagic,
            E::UnsupportedVersion(3),
            E::BadLength,
            E::BadChannelCount,
            E::BadTerms,
            E::BadCrc,
            E::NonFinite,
            E::BufferTooSmall,
            E::BadThermal,
        ];
        // Every code's name is its error's variant name.
        for e in errors {
            let debug = std::format!("{e:?}");
            let name = record_error_name(record_error_code(e)).unwrap();
            assert_eq!(debug.split('(').next().unwrap(), name);
        }
        assert_eq!(record_error_name(0), None);
        assert_eq!(record_error_name(11), None);
        let shown = |f: RecordFault| std::format!("{f}");
        assert_eq!(
            shown(RecordFault::BadRecord(record_error_code(E::UnsupportedVersion(3)))),
            "BadRecord(UnsupportedVersion): the record in force is invalid: its format version is not \
             1 or 2, the ones the node reads"
        );
        assert_eq!(
            shown(RecordFault::BadRecord(200)),
            "BadRecord(200): the record in force is invalid (reason code unknown to this host)"
        );
        assert!(shown(RecordFault::NotModel4).starts_with("NotModel4: the node applies model 4"));
        assert!(shown(RecordFault::WrongDevice).starts_with("WrongDevice: "));
    }

    #[test]
    fn random_bytes_never_panic() {
        let mut s = 0x2545_F491_4F6C_DD1Du64;
        let mut d = FrameDecoder::<MAX_FRAME>::new();
        let mut frames = 0;
        for _ in 0..20_000 {
            let mut chunk = [0u8; 64];
            for b in &mut chunk {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                // Zeros about one byte in 16, so many short frames form.
                *b = if s & 0xf == 0 { 0 } else { (s >> 32) as u8 };
            }
            d.push(&chunk, |_: Result<NodeMsg, _>| frames += 1);
            d.push(&chunk, |_: Result<HostMsg, _>| frames += 1);
        }
        assert!(frames > 10_000);
    }
}
