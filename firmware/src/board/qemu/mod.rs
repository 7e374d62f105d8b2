//! The QEMU board: what QEMU 10's `b-l475e-iot01a` machine really emulates (see
//! `shared/docs/qemu-b-l475e.md`). USART1 is the host link (the first `-serial`), time is the
//! host's clock (semihosting) with SysTick firing the alarms, defmt goes out over semihosting.
//! The ADC, DMA and timers are stubs in QEMU, so live sample sets come from an emulated analog
//! front end on USART2 (the second `-serial`, [`frontend`]), and replayed ones over the link as
//! replay requests. The node never enables USART3 (the host may attach a chardev to it to keep
//! QEMU's main loop busy).
//!
//! QEMU 10.0.2 models RCC: RCC_CSR reads 0x0C00_0600 after QEMU's reset (BORRSTF | PINRSTF |
//! MSISRANGE 6, the chip's power-on value), so the node reads and reports it like the real board
//! ([`ResetCause::PowerOn`]) and clears it (RMVF). The IWDG is an unimplemented-device stub (reads
//! 0, ignores writes, `info mtree`: "IWDG", priority −1000): there is no watchdog to feed. TIM6
//! and the ADC are stubs too: [`SampleClockImpl`] accepts every rate the app passes, tells the
//! front end (which paces the sets), and has no trigger configuration to read back.

mod frontend;
mod time;
mod usart;

use core::ptr::{read_volatile, write_volatile};

use accelcal_shared::slots::{SlotRead, SLOT_SIZE};
use accelcal_shared::wire::{ResetCause, DEFAULT_RATE_HZ};
use cortex_m_rt::exception;
use defmt_semihosting as _;

use accelcal_shared::boot::TempInputs;

use super::Board;
use crate::app::ports::{RecordStorage, SampleClock, Watchdog};

/// The board's temperature input: the emulated front end's channel ([`frontend`]); QEMU's ADC is
/// a stub, so there is no MCU sensor. A record naming the MCU's sensor is refused at boot.
pub const TEMP_INPUTS: TempInputs = TempInputs::FRONT_END;

pub use frontend::{SourceImpl, RING_SETS};
pub use usart::{LinkRxImpl, LinkTxImpl};

/// RCC_CSR (RM0351 §6.4.29): reset flags in bits 24..=31, RMVF (write 1 to clear them) bit 23.
const RCC_CSR: usize = 0x4002_1000 + 0x94;
const RCC_CSR_RMVF: u32 = 1 << 23;

/// Reads the reset flags and clears them (RMVF), so that the next boot sees only its own.
fn take_reset_cause() -> ResetCause {
    // SAFETY: RCC_CSR is a 32-bit RCC register, modelled by QEMU; nothing else touches it.
    let csr = unsafe { read_volatile(RCC_CSR as *const u32) };
    // SAFETY: as above; setting RMVF only clears the reset flags.
    unsafe { write_volatile(RCC_CSR as *mut u32, csr | RCC_CSR_RMVF) };
    defmt::info!("RCC_CSR at boot: {=u32:#010x}", csr);
    ResetCause::from_rcc_csr(csr)
}

/// The sampling rate: QEMU's TIM6 and ADC are stubs, so the front end paces the sets; it is told
/// every new rate ([`accelcal_shared::frontend::FeCtl::Rate`] on USART2).
pub struct SampleClockImpl {
    rate_hz: u32,
}

impl SampleClock for SampleClockImpl {
    fn rate_hz(&self) -> u32 {
        self.rate_hz
    }
    fn set_rate(&mut self, hz: u32) -> bool {
        self.rate_hz = hz;
        frontend::send_rate(hz);
        true
    }
    fn trigger_ok(&self) -> bool {
        true
    }
}

/// No watchdog: QEMU's IWDG is a stub. The main loop's progress rule runs all the same.
pub struct WatchdogImpl;

/// The watchdog, started before [`init`] as on the real board (here: nothing to start).
pub fn start_watchdog() -> WatchdogImpl {
    WatchdogImpl
}

impl Watchdog for WatchdogImpl {
    fn feed(&mut self) {}
}

/// The device id the QEMU board reports when the emulator gave it none
/// ([`accelcal_shared::contract::QEMU_DEVICE_ID`]). QEMU 10 does not map the unique-id area
/// (`contract::UID_ADDR`: reading it faults), so records meant for the emulated node carry this id.
pub const QEMU_DEVICE_ID: [u8; 12] = accelcal_shared::contract::QEMU_DEVICE_ID;

/// The emulated node's device id: the block the emulator loaded at
/// [`accelcal_shared::contract::QEMU_ID_ADDR`] (SRAM2, which the application does not use) for
/// the second and later nodes on one emulated head, else [`QEMU_DEVICE_ID`].
fn emulated_device_id() -> [u8; 12] {
    use accelcal_shared::contract::{qemu_device_id, QEMU_ID_ADDR, QEMU_ID_BLOCK_LEN};
    let mut block = [0u8; QEMU_ID_BLOCK_LEN];
    for (i, b) in block.iter_mut().enumerate() {
        // SAFETY: SRAM2 is mapped by QEMU's machine and outside every linker region (memory.x),
        // so nothing of the application lives there; a byte read of RAM has no side effect.
        *b = unsafe { read_volatile((QEMU_ID_ADDR as usize + i) as *const u8) };
    }
    qemu_device_id(block)
}

/// Record slots in flash, and the emulated node's device id ([`emulated_device_id`]).
pub struct Storage;

impl RecordStorage for Storage {
    /// QEMU's flash has no ECC: every slot reads completely.
    fn read_slot(&self, slot: u8, out: &mut [u8; SLOT_SIZE]) -> SlotRead {
        super::read_slot_with(slot, out, || false)
    }
    fn device_id(&self) -> [u8; 12] {
        emulated_device_id()
    }
}

/// Brings up the emulated chip: reset cause, time base (host clock, SysTick), USART1 (link),
/// USART2 (front end, told the sampling rate at boot).
pub fn init() -> Board {
    let reset_cause = take_reset_cause();
    let mut core = cortex_m::Peripherals::take().expect("init runs once");
    time::init(&mut core.SYST);
    let (rx, tx) = usart::init();
    let source = frontend::init(DEFAULT_RATE_HZ);
    let clock = SampleClockImpl { rate_hz: DEFAULT_RATE_HZ };
    Board { rx, tx, storage: Storage, source, clock, reset_cause }
}

/// Device interrupts: cortex-m-rt routes every one to `DefaultHandler`; dispatch on the number.
#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    if irqn == usart::USART1_IRQN {
        usart::on_interrupt();
    } else if irqn == frontend::USART2_IRQN {
        frontend::on_interrupt();
    } else {
        fail(format_args!("unexpected interrupt {irqn}"));
    }
}

#[exception]
unsafe fn HardFault(ef: &cortex_m_rt::ExceptionFrame) -> ! {
    fail(format_args!("hard fault at pc {:#010x}", ef.pc()))
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    fail(format_args!("{info}"))
}

/// Reports on QEMU's stderr (semihosting) and ends the emulation with a failure status.
fn fail(msg: core::fmt::Arguments) -> ! {
    cortex_m::interrupt::disable();
    cortex_m_semihosting::heprintln!("node: {}", msg);
    cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
    #[allow(clippy::empty_loop)]
    loop {}
}
