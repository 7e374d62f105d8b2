//! USART1, the host link, by 32-bit register access: QEMU's stm32l4x5 USART model accepts only word
//! accesses (embassy-stm32's byte-wide TDR write faults there). Reception is interrupt-driven into a
//! pipe with flow control: when the pipe is full the interrupt leaves the byte in RDR and masks
//! itself, so QEMU holds further input back and nothing is lost. [`Usart`] is the register access
//! both USARTs of this board use (USART2, the front end, in `frontend.rs`).

use core::ptr::{read_volatile, write_volatile};

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;

use crate::app::ports::{LinkRx, LinkTx};

/// USART1 base address (RM0351 §2.2.2, memory map, APB2).
const USART1: Usart = Usart { base: 0x4001_3800 };
/// USART_CR1 (RM0351 §40.8.1): UE bit 0, RE bit 2, TE bit 3, RXNEIE bit 5.
const CR1: usize = 0x00;
pub(super) const CR1_UE: u32 = 1 << 0;
pub(super) const CR1_RE: u32 = 1 << 2;
pub(super) const CR1_TE: u32 = 1 << 3;
pub(super) const CR1_RXNEIE: u32 = 1 << 5;
/// USART_BRR (RM0351 §40.8.4): USARTDIV = f_CK / baud for 16x oversampling.
const BRR: usize = 0x0C;
/// USART_ISR (RM0351 §40.8.8): ORE bit 3, RXNE bit 5, TXE bit 7.
const ISR: usize = 0x1C;
const ISR_ORE: u32 = 1 << 3;
const ISR_RXNE: u32 = 1 << 5;
const ISR_TXE: u32 = 1 << 7;
/// USART_ICR (RM0351 §40.8.9): ORECF bit 3.
const ICR: usize = 0x20;
/// USART_RDR and USART_TDR (RM0351 §40.8.10, §40.8.11).
const RDR: usize = 0x24;
const TDR: usize = 0x28;
/// RCC_APB2ENR (RM0351 §6.4.22): USART1EN bit 14.
const RCC_APB2ENR: usize = 0x4002_1000 + 0x60;
const RCC_APB2ENR_USART1EN: u32 = 1 << 14;
/// USART1 global interrupt: position 37 of the vector table (RM0351 §11.3, Table 58).
pub(super) const USART1_IRQN: i16 = 37;
/// Kernel clock after reset: MSI at 4 MHz (RM0351 §6.2.3); QEMU ignores the baud rate anyway.
const F_CK_HZ: u32 = 4_000_000;
const BAUD: u32 = accelcal_shared::contract::BAUD_QEMU;

static RX_PIPE: Pipe<CriticalSectionRawMutex, 256> = Pipe::new();

/// Reads a 32-bit peripheral register (RCC, a USART) at `addr`.
pub(super) fn reg_read(addr: usize) -> u32 {
    // SAFETY: callers pass 32-bit aligned registers of RCC or a USART, which exist on this chip.
    unsafe { read_volatile(addr as *const u32) }
}

/// Writes a 32-bit peripheral register (RCC, a USART) at `addr`.
pub(super) fn reg_write(addr: usize, v: u32) {
    // SAFETY: as in `reg_read`; word access is what QEMU's model requires.
    unsafe { write_volatile(addr as *mut u32, v) }
}

/// One USART's registers (RM0351 §40.8), by 32-bit access.
#[derive(Clone, Copy)]
pub(super) struct Usart {
    /// Base address.
    pub base: usize,
}

impl Usart {
    fn read(self, off: usize) -> u32 {
        reg_read(self.base + off)
    }

    fn write(self, off: usize, v: u32) {
        reg_write(self.base + off, v)
    }

    /// Configures 8N1 at [`BAUD`] (the kernel clock is MSI's after reset) and sets CR1 to `cr1`
    /// (UE is added). The caller has enabled the USART's clock.
    pub fn enable(self, cr1: u32) {
        self.write(BRR, F_CK_HZ / BAUD);
        self.write(CR1, cr1 | CR1_UE);
    }

    /// Sets or clears bits of CR1, in a critical section (thread mode and the interrupt share it).
    pub fn modify_cr1(self, set: u32, clear: u32) {
        critical_section::with(|_| self.write(CR1, (self.read(CR1) & !clear) | set));
    }

    /// Whether RDR holds a byte; clears an overrun on the way (one read of ISR: every register
    /// access is a trip into QEMU's device model, which the link's speed in QEMU depends on).
    pub fn rx_pending(self) -> bool {
        let isr = self.read(ISR);
        if isr & ISR_ORE != 0 {
            self.write(ICR, ISR_ORE);
        }
        isr & ISR_RXNE != 0
    }

    /// Takes the byte in RDR (the caller has seen [`Usart::rx_pending`]).
    pub fn read_rdr(self) -> u8 {
        self.read(RDR) as u8
    }

    /// Whether TDR can take a byte.
    pub fn tx_ready(self) -> bool {
        self.read(ISR) & ISR_TXE != 0
    }

    /// Writes a byte to TDR (the caller has seen [`Usart::tx_ready`]).
    pub fn transmit(self, b: u8) {
        self.write(TDR, b as u32);
    }
}

#[derive(Clone, Copy)]
pub(super) struct Irq(pub i16);
// SAFETY: callers build it from this chip's interrupt numbers (USART1_IRQN, USART2_IRQN).
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        self.0 as u16
    }
}

/// Enables the USART1 clock, configures 115200 8N1, enables transmitter, receiver and the
/// receive interrupt.
pub(super) fn init() -> (LinkRxImpl, LinkTxImpl) {
    reg_write(RCC_APB2ENR, reg_read(RCC_APB2ENR) | RCC_APB2ENR_USART1EN);
    USART1.enable(CR1_RE | CR1_TE | CR1_RXNEIE);
    // SAFETY: the handler (`on_interrupt`) only touches RX_PIPE and USART1 registers.
    unsafe { cortex_m::peripheral::NVIC::unmask(Irq(USART1_IRQN)) };
    (LinkRxImpl { _private: () }, LinkTxImpl { _private: () })
}

/// USART1 interrupt: moves received bytes into the pipe; masks itself when the pipe is full.
pub(super) fn on_interrupt() {
    while USART1.rx_pending() {
        if RX_PIPE.is_full() {
            USART1.modify_cr1(0, CR1_RXNEIE);
            break;
        }
        let _ = RX_PIPE.try_write(&[USART1.read_rdr()]);
    }
}

/// Receiving half of USART1.
pub struct LinkRxImpl {
    _private: (),
}

impl LinkRx for LinkRxImpl {
    async fn read(&mut self, buf: &mut [u8]) -> usize {
        let n = RX_PIPE.read(buf).await;
        // Room again: let the interrupt take bytes from RDR.
        USART1.modify_cr1(CR1_RXNEIE, 0);
        n
    }
}

/// Sending half of USART1.
pub struct LinkTxImpl {
    _private: (),
}

impl LinkTx for LinkTxImpl {
    async fn write_all(&mut self, bytes: &[u8]) {
        for &b in bytes {
            while !USART1.tx_ready() {
                embassy_futures::yield_now().await;
            }
            USART1.transmit(b);
        }
    }
}
