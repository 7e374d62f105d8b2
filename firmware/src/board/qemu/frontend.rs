//! USART2: the emulated analog front end, the QEMU board's live sample source (the second
//! `-serial` of QEMU; the contract is `accelcal_shared::frontend`).
//!
//! The front end sends one [`FeSet`] frame per sampling period. The receive interrupt drains RDR
//! every time (there is NO flow control on this port, unlike USART1: an ADC does not wait for the
//! firmware either), decodes the frames and appends their code sets, each with its temperature
//! ([`FeSet::temp_c`], the board's only temperature input), to a ring of
//! [`RING_SETS`] sets. A set that finds the ring full is dropped and counted, and a jump in
//! [`FeSet::index`] is counted as sets lost ([`frontend::lost_between`]); either count is attached
//! to the next set that enters the ring, so that the sampler reports the loss
//! ([`Overrun`]) exactly where it happened in the sequence and the node's sample counter stays
//! equal to the front end's index (mod 2¹⁶; the first set expected is index 0). A loss after the
//! last set received is reported when the next set arrives.
//!
//! [`SourceImpl::read_block`] returns blocks of [`MAX_BLOCK`] sets, like the real board's DMA half
//! buffers; only a block followed by a loss is shorter, ending where the loss is.
//!
//! The node tells the front end its sampling rate with [`FeCtl::Rate`] on USART2's transmitter
//! ([`send_rate`]): at boot, once the receiver is on (a front end that waits for it never sends
//! into a disabled receiver), and on every accepted rate change.

use core::cell::RefCell;
use core::future::poll_fn;
use core::task::Poll;

use accelcal_shared::frontend::{self, FeCtl, FeSet, FE_MAX_FRAME};
use accelcal_shared::wire::{self, Codes, FrameDecoder, MAX_BLOCK};
use critical_section::Mutex;
use embassy_sync::waitqueue::AtomicWaker;

use super::usart::{reg_read, reg_write, Irq, Usart, CR1_RE, CR1_RXNEIE, CR1_TE};
use crate::app::ports::{Overrun, SampleSource};

/// USART2 base address (RM0351 §2.2.2, memory map, APB1).
const USART2: Usart = Usart { base: 0x4000_4400 };
/// RCC_APB1ENR1 (RM0351 §6.4.19): USART2EN bit 17.
const RCC_APB1ENR1: usize = 0x4002_1000 + 0x58;
const RCC_APB1ENR1_USART2EN: u32 = 1 << 17;
/// USART2 global interrupt: position 38 of the vector table (RM0351 §11.3, Table 58).
pub(super) const USART2_IRQN: i16 = 38;

/// Sets the ring holds: two blocks, like the real board's ADC DMA ring (`board/real.rs`: two
/// halves of [`MAX_BLOCK`] scans). The sampler takes one block while the other fills, so the
/// emulated node has the same latency budget as the real one (one block period, 16 ms at 1 kHz)
/// before it loses sets, and a node that would overrun on the board overruns here too.
pub const RING_SETS: usize = 2 * MAX_BLOCK;

/// A set in the ring with its temperature, and how many sets were lost just before it.
#[derive(Clone, Copy)]
struct Entry {
    codes: Codes,
    temp_c: f32,
    lost_before: u32,
}

/// The receive side's state, shared by the interrupt and the sampler.
struct State {
    ring: [Entry; RING_SETS],
    /// Index of the oldest set.
    head: usize,
    /// Sets in the ring.
    len: usize,
    /// Sets lost since the newest set in the ring (attached to the next one that enters).
    pending_lost: u32,
    /// Index of the last set received (u16::MAX before the first: index 0 comes first).
    prev_index: u16,
    /// A frame that does not decode is passed over: the set it carried shows as an index jump.
    decoder: FrameDecoder<FE_MAX_FRAME>,
}

static STATE: Mutex<RefCell<State>> = Mutex::new(RefCell::new(State {
    ring: [Entry { codes: [0; 3], temp_c: 0.0, lost_before: 0 }; RING_SETS],
    head: 0,
    len: 0,
    pending_lost: 0,
    prev_index: u16::MAX,
    decoder: FrameDecoder::new(),
}));

static WAKER: AtomicWaker = AtomicWaker::new();

impl State {
    /// Feeds one received byte to the frame decoder; a decoded set enters the ring.
    fn push_byte(&mut self, b: u8) {
        let mut got = None;
        self.decoder.push(&[b], |m: Result<FeSet, _>| got = Some(m));
        if let Some(Ok(set)) = got {
            self.push_set(set);
        }
    }

    fn push_set(&mut self, set: FeSet) {
        let lost = frontend::lost_between(self.prev_index, set.index);
        self.prev_index = set.index;
        if self.len == RING_SETS {
            self.pending_lost = self.pending_lost.saturating_add(lost).saturating_add(1);
            return;
        }
        let at = (self.head + self.len) % RING_SETS;
        self.ring[at] = Entry {
            codes: set.codes,
            temp_c: set.temp_c(),
            lost_before: self.pending_lost.saturating_add(lost),
        };
        self.pending_lost = 0;
        self.len += 1;
    }

    /// The next loss or block, if one is ready: a loss before the oldest set first; else the sets
    /// up to the next loss or [`MAX_BLOCK`], once a full block or a loss after it is there.
    fn take(
        &mut self,
        out: &mut [Codes; MAX_BLOCK],
        temp_c: &mut [f32; MAX_BLOCK],
    ) -> Option<Result<usize, Overrun>> {
        if self.len == 0 {
            return None;
        }
        let lost = core::mem::take(&mut self.ring[self.head].lost_before);
        if lost > 0 {
            return Some(Err(Overrun { lost }));
        }
        let mut n = 1;
        while n < self.len.min(MAX_BLOCK) && self.ring[(self.head + n) % RING_SETS].lost_before == 0 {
            n += 1;
        }
        if n < MAX_BLOCK && n == self.len {
            return None;
        }
        for (k, (o, t)) in out.iter_mut().zip(temp_c.iter_mut()).take(n).enumerate() {
            let e = &self.ring[(self.head + k) % RING_SETS];
            (*o, *t) = (e.codes, e.temp_c);
        }
        self.head = (self.head + n) % RING_SETS;
        self.len -= n;
        Some(Ok(n))
    }
}

/// Enables the USART2 clock, its transmitter, receiver and receive interrupt, and tells the front
/// end the sampling rate in force.
pub(super) fn init(rate_hz: u32) -> SourceImpl {
    reg_write(RCC_APB1ENR1, reg_read(RCC_APB1ENR1) | RCC_APB1ENR1_USART2EN);
    USART2.enable(CR1_RE | CR1_TE | CR1_RXNEIE);
    // SAFETY: the handler (`on_interrupt`) only touches STATE, WAKER and USART2 registers.
    unsafe { cortex_m::peripheral::NVIC::unmask(Irq(USART2_IRQN)) };
    send_rate(rate_hz);
    SourceImpl { _private: () }
}

/// Sends [`FeCtl::Rate`] to the front end (a few bytes; QEMU's transmitter is never busy for long).
pub(super) fn send_rate(hz: u32) {
    let mut buf = [0u8; FE_MAX_FRAME];
    match wire::encode(&FeCtl::Rate { hz }, &mut buf) {
        Ok(frame) => {
            for &b in frame.iter() {
                while !USART2.tx_ready() {}
                USART2.transmit(b);
            }
        }
        // Unreachable: FE_MAX_FRAME holds every FeCtl (tested in shared).
        Err(e) => defmt::error!("front-end frame encode failed: {}", e),
    }
}

/// USART2 interrupt: takes every received byte (no flow control) into the decoder and the ring.
pub(super) fn on_interrupt() {
    let mut any = false;
    while USART2.rx_pending() {
        let b = USART2.read_rdr();
        critical_section::with(|cs| STATE.borrow_ref_mut(cs).push_byte(b));
        any = true;
    }
    if any {
        WAKER.wake();
    }
}

/// The front end's code sets (USART2).
pub struct SourceImpl {
    _private: (),
}

impl SampleSource for SourceImpl {
    async fn read_block(
        &mut self,
        out: &mut [Codes; MAX_BLOCK],
        temp_c: &mut [f32; MAX_BLOCK],
    ) -> Result<usize, Overrun> {
        poll_fn(|cx| {
            WAKER.register(cx.waker());
            match critical_section::with(|cs| STATE.borrow_ref_mut(cs).take(out, temp_c)) {
                Some(r) => Poll::Ready(r),
                None => Poll::Pending,
            }
        })
        .await
    }
}
