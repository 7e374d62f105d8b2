//! The QEMU board: what QEMU 10's `b-l475e-iot01a` machine really emulates (see
//! `shared/docs/qemu-b-l475e.md`). USART1 is the host link (`-serial`), time comes from SysTick,
//! defmt goes out over semihosting, and sample sets arrive over the link as replay requests (the
//! ADC, DMA and timers are stubs in QEMU, so there is no live sample source).

mod time;
mod usart;

use accelcal_shared::slots::{SlotRead, SLOT_SIZE};
use cortex_m_rt::exception;
use defmt_semihosting as _;

use crate::app::ports::RecordStorage;

pub use usart::{LinkRxImpl, LinkTxImpl};

/// Live sampling rate: none, samples arrive over the link.
pub const SAMPLE_RATE_HZ: u32 = 0;

/// The device id the QEMU board reports ([`accelcal_shared::contract::QEMU_DEVICE_ID`]). QEMU 10
/// does not map the unique-id area (`contract::UID_ADDR`: reading it faults), so records meant for
/// the emulated node carry this id.
pub const QEMU_DEVICE_ID: [u8; 12] = accelcal_shared::contract::QEMU_DEVICE_ID;

/// Record slots in flash, and the emulated node's device id.
pub struct Storage;

impl RecordStorage for Storage {
    /// QEMU's flash has no ECC: every slot reads completely.
    fn read_slot(&self, slot: u8, out: &mut [u8; SLOT_SIZE]) -> SlotRead {
        super::read_slot_with(slot, out, || false)
    }
    fn device_id(&self) -> [u8; 12] {
        QEMU_DEVICE_ID
    }
}

/// The board's parts, ready for the application.
pub struct Board {
    /// Host link, receiving half.
    pub rx: LinkRxImpl,
    /// Host link, sending half.
    pub tx: LinkTxImpl,
    /// Record slots and device id.
    pub storage: Storage,
}

/// Brings up the emulated chip: SysTick time base, USART1.
pub fn init() -> Board {
    let mut core = cortex_m::Peripherals::take().expect("init runs once");
    time::init(&mut core.SYST);
    let (rx, tx) = usart::init();
    Board { rx, tx, storage: Storage }
}

/// Device interrupts: cortex-m-rt routes every one to `DefaultHandler`; dispatch on the number.
#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    if irqn == usart::USART1_IRQN {
        usart::on_interrupt();
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
