//! USART1 by 32-bit register access: QEMU's stm32l4x5 USART model accepts only word accesses
//! (embassy-stm32's byte-wide TDR write faults there). Reception is interrupt-driven into a pipe
//! with flow control: when the pipe is full the interrupt leaves the byte in RDR and masks itself,
//! so QEMU holds further input back and nothing is lost.

use core::ptr::{read_volatile, write_volatile};

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;

use crate::app::ports::{LinkRx, LinkTx};

/// USART1 base address (RM0351 §2.2.2, memory map, APB2).
const USART1: usize = 0x4001_3800;
/// USART_CR1 (RM0351 §40.8.1): UE bit 0, RE bit 2, TE bit 3, RXNEIE bit 5.
const CR1: usize = USART1;
const CR1_UE: u32 = 1 << 0;
const CR1_RE: u32 = 1 << 2;
const CR1_TE: u32 = 1 << 3;
const CR1_RXNEIE: u32 = 1 << 5;
/// USART_BRR (RM0351 §40.8.4): USARTDIV = f_CK / baud for 16x oversampling.
const BRR: usize = USART1 + 0x0C;
/// USART_ISR (RM0351 §40.8.8): ORE bit 3, RXNE bit 5, TXE bit 7.
const ISR: usize = USART1 + 0x1C;
const ISR_ORE: u32 = 1 << 3;
const ISR_RXNE: u32 = 1 << 5;
const ISR_TXE: u32 = 1 << 7;
/// USART_ICR (RM0351 §40.8.9): ORECF bit 3.
const ICR: usize = USART1 + 0x20;
/// USART_RDR and USART_TDR (RM0351 §40.8.10, §40.8.11).
const RDR: usize = USART1 + 0x24;
const TDR: usize = USART1 + 0x28;
/// RCC_APB2ENR (RM0351 §6.4.22): USART1EN bit 14.
const RCC_APB2ENR: usize = 0x4002_1000 + 0x60;
const RCC_APB2ENR_USART1EN: u32 = 1 << 14;
/// USART1 global interrupt: position 37 of the vector table (RM0351 §11.3, Table 58).
pub(super) const USART1_IRQN: i16 = 37;
/// Kernel clock after reset: MSI at 4 MHz (RM0351 §6.2.3); QEMU ignores the baud rate anyway.
const F_CK_HZ: u32 = 4_000_000;
const BAUD: u32 = accelcal_shared::contract::BAUD_QEMU;

static RX_PIPE: Pipe<CriticalSectionRawMutex, 256> = Pipe::new();

fn reg_read(addr: usize) -> u32 {
    // SAFETY: a 32-bit aligned peripheral register of USART1/RCC, which exists on this chip.
    unsafe { read_volatile(addr as *const u32) }
}

fn reg_write(addr: usize, v: u32) {
    // SAFETY: as in `reg_read`; word access is what QEMU's model requires.
    unsafe { write_volatile(addr as *mut u32, v) }
}

#[derive(Clone, Copy)]
struct Irq;
// SAFETY: 37 is USART1's interrupt number on the STM32L475 (see USART1_IRQN).
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        USART1_IRQN as u16
    }
}

/// Enables the USART1 clock, configures 115200 8N1, enables transmitter, receiver and the
/// receive interrupt.
pub(super) fn init() -> (LinkRxImpl, LinkTxImpl) {
    reg_write(RCC_APB2ENR, reg_read(RCC_APB2ENR) | RCC_APB2ENR_USART1EN);
    reg_write(BRR, F_CK_HZ / BAUD);
    reg_write(CR1, CR1_UE | CR1_RE | CR1_TE | CR1_RXNEIE);
    // SAFETY: the handler (`on_interrupt`) only touches RX_PIPE and USART1 registers.
    unsafe { cortex_m::peripheral::NVIC::unmask(Irq) };
    (LinkRxImpl { _private: () }, LinkTxImpl { _private: () })
}

/// USART1 interrupt: moves received bytes into the pipe; masks itself when the pipe is full.
pub(super) fn on_interrupt() {
    loop {
        let isr = reg_read(ISR);
        if isr & ISR_ORE != 0 {
            reg_write(ICR, ISR_ORE);
        }
        if isr & ISR_RXNE == 0 {
            break;
        }
        if RX_PIPE.is_full() {
            critical_section::with(|_| reg_write(CR1, reg_read(CR1) & !CR1_RXNEIE));
            break;
        }
        let b = reg_read(RDR) as u8;
        let _ = RX_PIPE.try_write(&[b]);
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
        critical_section::with(|_| reg_write(CR1, reg_read(CR1) | CR1_RXNEIE));
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
            while reg_read(ISR) & ISR_TXE == 0 {
                embassy_futures::yield_now().await;
            }
            reg_write(TDR, b as u32);
        }
    }
}
