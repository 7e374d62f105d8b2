//! The real B-L475E-IOT01A: embassy-stm32 drives the STM32L475VG. This is the only module that
//! imports `embassy_stm32`.
//!
//! Pins (Arduino header of the board):
//! - x: A0 = PC5 (ADC1_IN14), y: A1 = PC4 (ADC1_IN13), z: A2 = PC3 (ADC1_IN4);
//! - host link: USART1, PB6 = TX, PB7 = RX (AF7), wired to the ST-LINK virtual COM port.
//!
//! Sampling (RM0351 chapter 18, ADC): TIM6's update event (TRGO, RM0351 §30.4.2 TIMx_CR2
//! MMS = 010) triggers one regular scan of the three channels (CFGR EXTEN = 01 rising edge,
//! EXTSEL = 1101 TIM6_TRGO, RM0351 §18.4.18 Table 96). Each channel is converted 16 times and
//! summed by the hardware oversampler (CFGR2 ROVSE = 1, OVSR = 011 16x, OVSS = 0000 no shift,
//! TROVS = 0 one trigger for the whole burst, RM0351 §18.4.30): 12-bit conversions summed 16x give
//! 16-bit codes 0..=65520. DMA1 channel 1 (ADC1 request, RM0351 §11.6.7 Table 41) moves the codes
//! in circular mode into a ring buffer of two blocks; the sampler task reads one half while the
//! DMA fills the other. A lap of the ring is an overrun: counted and reported in every status.

use core::sync::atomic::{AtomicU8, Ordering};

use accelcal_shared::contract::BAUD_REAL;
use accelcal_shared::flash_ecc::{self, NmiAction};
use accelcal_shared::slots::{SlotRead, SLOT_SIZE};
use accelcal_shared::wire::{Codes, MAX_BLOCK};
use defmt_rtt as _;
use embassy_stm32::adc::{Adc, AdcChannel, AdcConfig, RingBufferedAdc, SampleTime, CONTINUOUS};
use embassy_stm32::pac::adc::vals::{OversamplingRatio, OversamplingShift, Rovsm, Trovs};
use embassy_stm32::pac::timer::vals::Mms;
use embassy_stm32::peripherals::{ADC1, TIM6};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::{RoundTo, Timer};
use embassy_stm32::usart::{self, RingBufferedUartRx, Uart, UartTx};
use embassy_stm32::{bind_interrupts, dma, mode::Async, peripherals, rcc, Config};
use panic_probe as _;

use crate::app::ports::{LinkRx, LinkTx, Overrun, RecordStorage, SampleSource};

/// Sampling rate per channel, Hz (the TIM6 update rate).
pub const SAMPLE_RATE_HZ: u32 = 1000;
/// USART1 baud rate ([`BAUD_REAL`]): 1 kHz of calibrated triads in blocks of 16 is about
/// 12.5 kB/s of frames.
pub const BAUD: u32 = BAUD_REAL;
/// Channels per sample set.
const N_CH: usize = 3;
/// EXTSEL value for TIM6_TRGO (RM0351 §18.4.18, Table 96: EXT13).
const EXTSEL_TIM6_TRGO: u8 = 13;
/// EXTEN value for a rising-edge hardware trigger (RM0351 §18.7.4, ADC_CFGR EXTEN = 01).
const EXTEN_RISING: u8 = 0b01;

bind_interrupts!(struct Irqs {
    USART1 => usart::InterruptHandler<peripherals::USART1>;
    DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    DMA1_CHANNEL4 => dma::InterruptHandler<peripherals::DMA1_CH4>;
    DMA1_CHANNEL5 => dma::InterruptHandler<peripherals::DMA1_CH5>;
});

/// Record slots in flash and the MCU's unique id.
pub struct Storage;

impl RecordStorage for Storage {
    fn read_slot(&self, slot: u8, out: &mut [u8; SLOT_SIZE]) -> SlotRead {
        let bit = 1u8.checked_shl(slot as u32).unwrap_or(0);
        SLOT_ECC_FAULTS.fetch_and(!bit, Ordering::SeqCst);
        super::read_slot_with(slot, out, || SLOT_ECC_FAULTS.load(Ordering::SeqCst) & bit != 0)
    }
    fn device_id(&self) -> [u8; 12] {
        embassy_stm32::uid::uid()
    }
}

/// Receiving half of USART1 (DMA ring buffer).
pub struct LinkRxImpl(RingBufferedUartRx<'static>);

impl LinkRx for LinkRxImpl {
    async fn read(&mut self, buf: &mut [u8]) -> usize {
        loop {
            match self.0.read(buf).await {
                Ok(n) if n > 0 => return n,
                Ok(_) => {}
                // Noise or an overrun on the line: the frame decoder resynchronises at the next
                // zero and counts the broken frame.
                Err(e) => defmt::warn!("usart1 receive error: {}", e),
            }
        }
    }
}

/// Sending half of USART1 (DMA).
pub struct LinkTxImpl(UartTx<'static, Async>);

impl LinkTx for LinkTxImpl {
    async fn write_all(&mut self, bytes: &[u8]) {
        if let Err(e) = self.0.write(bytes).await {
            defmt::warn!("usart1 transmit error: {}", e);
        }
    }
}

/// The ADC1 triad: timer-triggered, oversampled, DMA ring buffer.
pub struct SourceImpl {
    adc: RingBufferedAdc<'static, ADC1>,
    _timer: Timer<'static, TIM6>,
}

impl SampleSource for SourceImpl {
    fn rate_hz(&self) -> u32 {
        SAMPLE_RATE_HZ
    }

    async fn read_block(&mut self, out: &mut [Codes; MAX_BLOCK]) -> Result<usize, Overrun> {
        let mut raw = [0u16; MAX_BLOCK * N_CH];
        match self.adc.read(&mut raw).await {
            Ok(_) => {
                for (set, c) in out.iter_mut().zip(raw.chunks_exact(N_CH)) {
                    *set = [c[0], c[1], c[2]];
                }
                Ok(MAX_BLOCK)
            }
            Err(_) => {
                // The DMA lapped the reader: at least one block is gone. Restart from fresh data.
                self.adc.clear();
                Err(Overrun { lost: MAX_BLOCK as u32 })
            }
        }
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
    /// Live sample sets.
    pub source: SourceImpl,
}

fn clocks() -> Config {
    let mut config = Config::default();
    // SYSCLK 80 MHz from HSI16 through PLL1 (16 / 1 × 10 / 2), RM0351 §6.2.
    config.rcc.hsi = true;
    config.rcc.sys = rcc::Sysclk::PLL1_R;
    config.rcc.pll = Some(rcc::Pll {
        source: rcc::PllSource::HSI,
        prediv: rcc::PllPreDiv::DIV1,
        mul: rcc::PllMul::MUL10,
        divp: None,
        divq: None,
        divr: Some(rcc::PllRDiv::DIV2),
    });
    // ADC kernel clock: SYSCLK (RCC_CCIPR ADCSEL = 11, RM0351 §6.4.28).
    config.rcc.mux.adcsel = rcc::mux::Adcsel::SYS;
    config
}

/// Brings up clocks, USART1, TIM6 and ADC1 with DMA.
pub fn init() -> Board {
    let p = embassy_stm32::init(clocks());

    let mut uart_cfg = usart::Config::default();
    uart_cfg.baudrate = BAUD;
    let uart = Uart::new(p.USART1, p.PB7, p.PB6, p.DMA1_CH4, p.DMA1_CH5, Irqs, uart_cfg)
        .expect("USART1 configuration is valid");
    let (tx, rx) = uart.split();
    let rx_buf = cortex_m::singleton!(: [u8; 256] = [0; 256]).expect("init runs once");
    let rx = rx.into_ring_buffered(rx_buf);

    let adc_cfg = AdcConfig {
        oversampling_ratio: Some(OversamplingRatio::RATIO16),
        oversampling_shift: Some(OversamplingShift::SHIFT0),
        oversampling_mode: Some((Rovsm::CONTINUED, Trovs::AUTOMATIC, true)),
        ..Default::default()
    };
    let adc = Adc::new_with_config(p.ADC1, adc_cfg);
    let dma_buf = cortex_m::singleton!(: [u16; 2 * MAX_BLOCK * N_CH] = [0; 2 * MAX_BLOCK * N_CH])
        .expect("init runs once");
    let sequence = [
        (p.PC5.degrade_adc(), SampleTime::CYCLES47_5),
        (p.PC4.degrade_adc(), SampleTime::CYCLES47_5),
        (p.PC3.degrade_adc(), SampleTime::CYCLES47_5),
    ];
    let mut adc = adc.into_ring_buffered(p.DMA1_CH1, dma_buf, Irqs, sequence.into_iter(), CONTINUOUS);
    // embassy-stm32 sets up continuous conversions on this ADC version; switch to one scan per
    // TIM6 trigger (CFGR CONT = 0, EXTEN = rising, EXTSEL = TIM6_TRGO; RM0351 §18.7.4).
    embassy_stm32::pac::ADC1.cfgr().modify(|w| {
        w.set_cont(false);
        w.set_exten(EXTEN_RISING);
        w.set_extsel(EXTSEL_TIM6_TRGO);
    });

    let timer = Timer::new(p.TIM6);
    timer.set_frequency(Hertz(SAMPLE_RATE_HZ), RoundTo::Slower);
    // TRGO on every update event (TIM6_CR2 MMS = 010, RM0351 §30.4.2).
    timer.regs_basic().cr2().modify(|w| w.set_mms(Mms::UPDATE));
    adc.start();
    timer.start();

    Board {
        rx: LinkRxImpl(rx),
        tx: LinkTxImpl(tx),
        storage: Storage,
        source: SourceImpl { adc, _timer: timer },
    }
}

/// Record slots in which a double ECC error was reported (bit n: slot n), set by the NMI handler.
static SLOT_ECC_FAULTS: AtomicU8 = AtomicU8::new(0);

/// The NMI: a double ECC error in a record slot (a write or erase cut by a power loss) is cleared
/// and marks the slot unreadable, so that reading it yields "slot invalid" instead of hanging the
/// boot (cortex-m-rt's default NMI handler loops forever); any other NMI resets the MCU. The
/// decision is `accelcal_shared::flash_ecc::nmi_action`; FLASH_ECCR is RM0351 §3.7.8 (ECCD is
/// write-1-to-clear). The load that raised the error completes with meaningless data, which
/// `board::read_slot_with` discards.
///
/// SAFETY (cortex-m-rt's requirement for an NMI handler): it touches no data protected by a
/// critical section, only FLASH_ECCR, an atomic, and the reset request.
#[cortex_m_rt::exception]
unsafe fn NonMaskableInt() {
    let eccr = embassy_stm32::pac::FLASH.eccr();
    match flash_ecc::nmi_action(eccr.read().0) {
        NmiAction::SlotUnreadable { slot, clear } => {
            eccr.write_value(embassy_stm32::pac::flash::regs::Eccr(clear));
            SLOT_ECC_FAULTS.fetch_or(1 << slot, Ordering::SeqCst);
        }
        NmiAction::Reset => cortex_m::peripheral::SCB::sys_reset(),
    }
}
