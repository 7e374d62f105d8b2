//! The real B-L475E-IOT01A: embassy-stm32 drives the STM32L475VG. This is the only module that
//! imports `embassy_stm32`.
//!
//! Pins (Arduino header of the board):
//! - x: A0 = PC5 (ADC1_IN14), y: A1 = PC4 (ADC1_IN13), z: A2 = PC3 (ADC1_IN4);
//! - host link: USART1, PB6 = TX, PB7 = RX (AF7), wired to the ST-LINK virtual COM port.
//!
//! Sampling (RM0351 chapter 18, ADC): TIM6's update event (TRGO, RM0351 §30.4.2 TIMx_CR2
//! MMS = 010) triggers one regular scan (CFGR EXTEN = 01 rising edge, EXTSEL = 1101 TIM6_TRGO,
//! RM0351 §18.4.18 Table 96) of four conversions: VREFINT (ADC1_IN0), whose result is discarded,
//! then x, y, z. The discarded first conversion is the workaround of the STM32L4 erratum "wrong ADC
//! result if conversion done late after calibration or previous conversion" (errata sheet ES0250,
//! ADC section; embassy-stm32 0.6.0 `src/adc/v3.rs` `convert` handles it too: a
//! conversion more than 1 ms after the previous one may be wrong; convert twice, keep the
//! second), so every rate in `wire::RATE_MIN_HZ..=RATE_MAX_HZ` is safe, and so is the first scan
//! after boot or a rate change. Each channel is converted 16 times and summed by the hardware
//! oversampler (CFGR2 ROVSE = 1, OVSR = 011 16x, OVSS = 0000 no shift, TROVS = 0 one trigger for
//! the whole burst, RM0351 §18.4.30): 12-bit conversions summed 16x give 16-bit codes 0..=65520.
//! Sampling time 247.5 ADC cycles on x, y, z (firmware/README.md says why), 2.5 on the discarded
//! conversion. DMA1 channel 1 (ADC1 request, RM0351 §11.6.7 Table 41) moves the codes in circular
//! mode into a ring buffer of two blocks; the sampler task reads one half while the DMA fills the
//! other. A lap of the ring is an overrun, and the sets it lost are measured, not assumed
//! ([`SourceImpl::measure_overrun`]): embassy-stm32 0.6.0's ring reports an overrun only once
//! more than the whole ring is unread and then jumps the reader to the DMA's position, so the
//! loss is any number of sets. TIM6's rate is set at run time ([`SampleClockImpl`]), and the
//! trigger configuration is read back from the registers at boot and after every change.
//!
//! Temperature (the board's only temperature input, [`TEMP_INPUTS`]): the MCU's internal sensor,
//! ADC1 channel 17 (ADC_CCR CH17SEL, RM0351 §18.4.32), read once per block by an injected
//! sequence started by software (ADC_JSQR JEXTEN = 00, JADSTART; RM0351 §18.4.20, "Injected
//! channel management") right after the DMA has delivered a block, when the regular scan has just
//! ended: two conversions of channel 17, the first discarded for the same erratum as the regular
//! scan's first rank, 640.5 ADC cycles each (the datasheet's minimum sampling time of the sensor
//! is 5 µs; 640.5 cycles are 8.0 µs at 80 MHz), not oversampled (CFGR2 JOVSE = 0): 1306 ADC
//! cycles, 16.3 µs. An injected sequence that meets a running regular scan interrupts it and the
//! regular oversampling resumes where it stopped (CFGR2 ROVSM = 0, "continued"), so the scan
//! ends 16.3 µs late, still before the next trigger at every rate up to
//! [`RATE_MAX_HZ`](accelcal_shared::wire::RATE_MAX_HZ)
//! (159 + 16.3 µs < 250 µs). Embassy-stm32 0.6.0 has injected-sequence support on the G4 ADC only
//! (`src/adc/g4.rs`), so the registers are programmed here through its PAC (stm32-metapac 21
//! `peripherals/adc_v3.rs`: JSQR, JDR, ISR.JEOS, CR.JADSTART; JQDIS, CFGR bit 31, is not in the
//! PAC and keeps its reset value 1, which software triggers need). The reading is converted with
//! the part's factory calibration ([`accelcal_shared::mcu_temp`]: TS_CAL1, TS_CAL2 and VREFINT_CAL
//! from system memory, VDDA from one VREFINT reading at boot) and every set of the block carries
//! it; the application's shared tracker filters it. A part whose calibration values are not
//! plausible reads NaN, which a thermal record flags as out of range.
//!
//! Watchdog: the IWDG with a 4 s timeout, started before anything else is brought up
//! ([`start_watchdog`]) and fed by the executor's loop while the sampler and the link make
//! progress; frozen while a debugger halts the core (DBGMCU_APB1FZR1 DBG_IWDG_STOP) so that
//! `accelcal flash`, which halts the core, is never interrupted by it. TIM2 (embassy-time's
//! driver, whose count of counter overflows needs its interrupt every 32.8 ms) and TIM6 (the ADC's
//! trigger) are frozen with it, so that a halt stops the time and the sampling together and the
//! overrun measurement's two clocks never disagree. A panic or a hard fault logs over defmt and
//! resets the MCU (`SCB::sys_reset`, reported as `ResetCause::Software` at the next boot); with
//! the `debug-panic` feature, panic-probe halts instead, for a debugger.

use core::cell::Cell;
use core::sync::atomic::{AtomicU8, Ordering};

use accelcal_shared::boot::TempInputs;
use accelcal_shared::contract::BAUD_REAL;
use accelcal_shared::flash_ecc::{self, NmiAction};
use accelcal_shared::mcu_temp::{self, McuTempCal};
use accelcal_shared::overrun::Tracker;
use accelcal_shared::slots::{SlotRead, SLOT_SIZE};
use accelcal_shared::wire::{Codes, ResetCause, DEFAULT_RATE_HZ, LINK_RX_RING, MAX_BLOCK};
use critical_section::Mutex;
use defmt_rtt as _;
use embassy_stm32::adc::{Adc, AdcChannel, AdcConfig, RingBufferedAdc, SampleTime, CONTINUOUS};
use embassy_stm32::pac::adc::vals::{Dmacfg, OversamplingRatio, OversamplingShift, Rovsm, Trovs};
use embassy_stm32::pac::iwdg::vals::{Key, Pr};
use embassy_stm32::pac::timer::vals::Mms;
use embassy_stm32::peripherals::{ADC1, TIM6};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::{RoundTo, Timer};
use embassy_stm32::usart::{self, RingBufferedUartRx, Uart, UartTx};
use embassy_stm32::{bind_interrupts, dma, mode::Async, pac, peripherals, rcc, Config};
use embassy_time::Instant;
#[cfg(feature = "debug-panic")]
use panic_probe as _;

use super::Board;
use crate::app::ports::{LinkRx, LinkTx, Overrun, RecordStorage, SampleClock, SampleSource, Watchdog};

/// USART1 baud rate ([`BAUD_REAL`]): 4 kHz of calibrated triads in blocks of 16 is 50.5 kB/s of
/// frames, 55 % of it.
pub const BAUD: u32 = BAUD_REAL;
/// Independent watchdog timeout, µs: 4× the longest legitimate interval between feeds (the 1 s
/// status period, see `executor.rs`). [`IWDG_PR`] and [`IWDG_RELOAD`] give it at LSI = 32 kHz
/// (the value embassy-stm32 0.6.0's `IndependentWatchdog::new` picks too, `src/wdg/mod.rs`); the
/// STM32L475's LSI (29.5..=34 kHz in its datasheet) makes it 3.76..=4.34 s.
pub const WATCHDOG_TIMEOUT_US: u32 = 4_000_000;
/// IWDG_PR: LSI / 32, 1 kHz (RM0351 §32.4.2; stm32-metapac 21 `peripherals/iwdg_v2.rs`).
const IWDG_PR: Pr = Pr::DIVIDE_BY32;
/// IWDG_RLR: 4000 periods of 1 ms (RM0351 §32.4.3; the counter counts RL..=0).
const IWDG_RELOAD: u16 = (WATCHDOG_TIMEOUT_US / 1000 - 1) as u16;
/// Polls of IWDG_SR for the prescaler and reload updates (PVU, RVU: a few LSI periods after the
/// LSI starts, ≈ 0.3 ms): more than 10 ms at the 4 MHz MSI clock of the core before `init`.
const IWDG_UPDATE_POLLS: u32 = 20_000;
/// Conversions per scan: the discarded one, then x, y, z.
const N_SCAN: usize = 4;
/// Sets in the ADC's DMA ring: two blocks.
const RING_SETS: usize = 2 * MAX_BLOCK;
/// TIM6's kernel clock, MHz: APB1's timer clock, PCLK1 = SYSCLK = 80 MHz with the APB1 prescaler
/// at 1 ([`clocks`]; RM0351 §6.2, "Timer clock": ×1 when the APB prescaler is 1). `init` checks it
/// against embassy's `Timer::get_clock_frequency`.
const TIM6_CLOCK_MHZ: u32 = 80;
/// ADC1 channel of each rank of the scan: VREFINT (IN0, discarded), PC5 (IN14, x), PC4 (IN13, y),
/// PC3 (IN4, z).
const SCAN_CHANNELS: [u8; N_SCAN] = [0, 14, 13, 4];
/// Sampling time of x, y, z: 247.5 ADC cycles = 3.09 µs at 80 MHz (firmware/README.md, "ADC").
const SAMPLE_TIME: SampleTime = SampleTime::CYCLES247_5;
/// Sampling time of the discarded first conversion (its value is never used).
const DUMMY_SAMPLE_TIME: SampleTime = SampleTime::CYCLES2_5;
/// The board's temperature input: the MCU's sensor. The front end has no temperature channel, so
/// a record naming it is refused at boot.
pub const TEMP_INPUTS: TempInputs = TempInputs::MCU;
/// ADC1 channel of the temperature sensor (VSENSE, RM0351 §18.4.32).
const TEMP_CHANNEL: u8 = 17;
/// Sampling time of the temperature sensor and of VREFINT at boot: 640.5 ADC cycles = 8.0 µs at
/// 80 MHz (datasheet minimum 5 µs for the sensor, 4 µs for VREFINT).
const TEMP_SAMPLE_TIME: SampleTime = SampleTime::CYCLES640_5;
/// ADC_CFGR JQDIS (bit 31, RM0351 §18.7.4): injected queue disabled, needed for software
/// triggers of the injected sequence; its reset value, not modelled by stm32-metapac 21.
const CFGR_JQDIS: u32 = 1 << 31;
/// Hardware oversampling ratio of the regular scan and of the boot readings.
const OVERSAMPLING: f32 = 16.0;
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
        // Re-arm FLASH_ECCR's address capture (ECCC and ECCD cleared, ECCIE kept), so that an
        // error in this slot is reported with this slot's address (`flash_ecc::rearm`).
        let eccr = pac::FLASH.eccr();
        eccr.write_value(pac::flash::regs::Eccr(flash_ecc::rearm(eccr.read().0)));
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

/// The ADC1 triad: timer-triggered, oversampled, DMA ring buffer; and the MCU's temperature.
pub struct SourceImpl {
    adc: RingBufferedAdc<'static, ADC1>,
    temp: McuTemp,
}

/// The count of sample sets across overruns ([`Tracker`]): updated by the sampler after
/// every block and overrun ([`SourceImpl`]) and by [`SampleClockImpl`] at every rate change, so
/// shared by two tasks (thread mode, one executor; no interrupt touches it).
static TRACKER: Mutex<Cell<SetTracker>> = Mutex::new(Cell::new(SetTracker::new()));

/// The board's [`Tracker`]: the ADC ring's sets and scan length, TIM6's clock.
type SetTracker = Tracker<{ RING_SETS as u32 }, { N_SCAN as u32 }, TIM6_CLOCK_MHZ>;

/// Runs `f` on [`TRACKER`].
fn with_tracker<R>(f: impl FnOnce(&mut SetTracker) -> R) -> R {
    critical_section::with(|cs| {
        let cell = TRACKER.borrow(cs);
        let mut tracker = cell.get();
        let r = f(&mut tracker);
        cell.set(tracker);
        r
    })
}

/// embassy-time's clock, µs (the build's `tick-hz-1_000_000`), truncated to 32 bits.
#[inline(never)]
fn now_us() -> u32 {
    Instant::now().as_ticks() as u32
}

/// DMA1 channel 1's remaining transfers (CNDTR1, RM0351 §11.6.4; stm32-metapac 21
/// `peripherals/bdma_v2.rs`, `Ch::ndtr` at 0x08 + 20·n + 0x04): the ADC ring's write position,
/// counting down from the ring's length.
fn adc_dma_ndtr() -> u16 {
    pac::DMA1.ch(0).ndtr().read().ndt()
}

/// The temperature sensor's injected reading, once per block.
struct McuTemp {
    /// The part's calibration (`None`: implausible values, the temperature reads NaN).
    cal: Option<McuTempCal>,
    /// The last temperature read, °C.
    last_c: f32,
}

impl McuTemp {
    /// Programs the injected sequence (the regular scan is not running yet): channel 17 twice,
    /// software trigger, not oversampled, no auto-injection, no discontinuous mode.
    fn configure() {
        let adc = pac::ADC1;
        adc.cfgr().modify(|w| {
            w.set_jauto(false);
            w.set_jdiscen(false);
            w.0 |= CFGR_JQDIS;
        });
        adc.cfgr2().modify(|w| w.set_jovse(false));
        let ch = TEMP_CHANNEL as usize;
        adc.smpr(ch / 10).modify(|w| w.set_smp(ch % 10, TEMP_SAMPLE_TIME));
        adc.jsqr().write(|w| {
            w.set_jl(1);
            w.set_jsq(0, TEMP_CHANNEL);
            w.set_jsq(1, TEMP_CHANNEL);
            w.set_jexten(0);
        });
    }

    /// Starts the injected sequence.
    fn start() {
        pac::ADC1.cr().modify(|w| w.set_jadstart(true));
    }

    /// The temperature of the block just delivered: the sequence started after the previous
    /// block, if it has ended (the last temperature otherwise); then starts the next one.
    fn poll(&mut self) -> f32 {
        let adc = pac::ADC1;
        if adc.isr().read().jeos() {
            // JDR2: the second conversion (the first is the erratum's discarded one).
            let ts = adc.jdr(1).read().jdata();
            // ISR flags are write-1-to-clear: write JEOS and JEOC only, leave the regular flags.
            adc.isr().write(|w| {
                w.set_jeos(true);
                w.set_jeoc(true);
            });
            self.last_c = self.cal.map_or(f32::NAN, |c| c.temp_c(ts as f32));
            McuTemp::start();
        } else if !adc.cr().read().jadstart() {
            McuTemp::start();
        }
        self.last_c
    }
}

/// Reads a u16 of system memory (the factory calibration values).
fn read_system_u16(addr: u32) -> u16 {
    // SAFETY: the calibration values are read-only system memory of every STM32L475, mapped for
    // the program's lifetime (DS10969, "Temperature sensor calibration values"); 2-aligned.
    unsafe { core::ptr::read_volatile(addr as usize as *const u16) }
}

impl SampleSource for SourceImpl {
    async fn read_block(
        &mut self,
        out: &mut [Codes; MAX_BLOCK],
        temp_c: &mut [f32; MAX_BLOCK],
    ) -> Result<usize, Overrun> {
        let mut raw = [0u16; MAX_BLOCK * N_SCAN];
        match self.adc.read(&mut raw).await {
            Ok(unread) => {
                // Rank 1 of each scan is the erratum's discarded conversion.
                for (set, c) in out.iter_mut().zip(raw.chunks_exact(N_SCAN)) {
                    *set = [c[1], c[2], c[3]];
                }
                temp_c.fill(self.temp.poll());
                // `unread` values follow the block (embassy's `read_exact` returns them): the
                // count of scans begun is known exactly now.
                let now = now_us();
                with_tracker(|t| t.block(MAX_BLOCK as u32, unread as u32, now));
                Ok(MAX_BLOCK)
            }
            Err(_) => Err(Overrun { lost: self.measure_overrun() }),
        }
    }
}

impl SourceImpl {
    /// After the ring reported an overrun: moves the reader to the DMA's position (embassy's
    /// `clear`, `ReadableDmaRingBuffer::reset`: the reader resumes at the first whole scan at or
    /// after it) and returns the sets lost since the last block, measured
    /// ([`Tracker::overrun`]): modulo the ring from DMA1 channel 1's NDTR read on both sides of
    /// the move (equal: no transfer in between, so it is the position embassy read; the DMA's
    /// transfers are at least 52 µs apart, 16 × 260 ADC cycles, and the move takes about 1 µs),
    /// the laps from the time since the count was last known, at TIM6's period.
    #[inline(never)]
    fn measure_overrun(&mut self) -> u32 {
        let ndtr = loop {
            let before = adc_dma_ndtr();
            self.adc.clear();
            if adc_dma_ndtr() == before {
                break before;
            }
        };
        let now = now_us();
        let lost = with_tracker(|t| t.overrun(ndtr.into(), now));
        if lost.off_by.unsigned_abs() > 3 {
            defmt::error!(
                "overrun measurement: DMA and TIM6 period disagree by {=i32} sets (exact below {=u32})",
                lost.off_by,
                RING_SETS as u32 / 2
            );
        }
        lost.sets
    }
}

/// TIM6, the ADC's trigger: sets the sampling rate and reads the trigger configuration back.
pub struct SampleClockImpl {
    timer: Timer<'static, TIM6>,
    rate_hz: u32,
}

impl SampleClock for SampleClockImpl {
    fn rate_hz(&self) -> u32 {
        self.rate_hz
    }

    fn set_rate(&mut self, hz: u32) -> bool {
        self.timer.stop();
        let now = now_us();
        self.timer.set_frequency(Hertz(hz), RoundTo::Slower);
        self.timer.reset();
        // TIM6_PSC is preloaded (RM0351 §30.3.1): an update event loads it now. With MMS = update
        // this event is also a TRGO, so one scan starts at the change, off the new grid.
        self.timer.generate_update_event();
        self.timer.start();
        self.rate_hz = hz;
        // The count of scans goes on from those begun under the old period, plus the one the
        // update event starts, at the period PSC and ARR now give (TIM6's clock: TIM6_CLOCK_MHZ).
        let tim = self.timer.regs_basic();
        let period = (tim.psc().read() as u32 + 1).saturating_mul(tim.arr().read().arr() as u32 + 1);
        with_tracker(|t| t.rate_changed(now, period));
        self.trigger_ok()
    }

    fn trigger_ok(&self) -> bool {
        read_back_trigger(&self.timer, self.rate_hz)
    }
}

/// Compares a register field with what was programmed; logs a mismatch.
/// `name` is interned: it lives in the defmt table on the host, not in the node's flash.
fn field_ok(name: defmt::Str, got: u32, want: u32) -> bool {
    if got != want {
        defmt::error!("ADC trigger read-back: {=istr} = {=u32}, programmed {=u32}", name, got, want);
    }
    got == want
}

/// Reads back what paces and shapes the scans (register fields of stm32-metapac 21's
/// `peripherals/adc_v3.rs` and `peripherals/timer_v1.rs`, RM0351 §18.7 and §30.4): ADC1 CFGR
/// (EXTEN rising, EXTSEL TIM6_TRGO, CONT = 0, DMAEN, DMACFG circular), CR ADSTART, CFGR2 (16×
/// oversampling, no shift, TROVS = 0, ROVSE), SQR1 (4 ranks, channels 0, 14, 13, 4), SMPR1/2
/// (sampling times), TIM6 CR2 MMS = update, CR1 CEN, and the rate that PSC and ARR give (within
/// 0.1 % of `rate_hz`). Logs each field that differs; `true` when none does.
fn read_back_trigger(timer: &Timer<'static, TIM6>, rate_hz: u32) -> bool {
    let adc = pac::ADC1;
    let cfgr = adc.cfgr().read();
    let cfgr2 = adc.cfgr2().read();
    let sqr1 = adc.sqr1().read();
    let mut ok = field_ok(defmt::intern!("CFGR.EXTEN"), cfgr.exten().into(), EXTEN_RISING.into());
    ok &= field_ok(defmt::intern!("CFGR.EXTSEL"), cfgr.extsel().into(), EXTSEL_TIM6_TRGO.into());
    ok &= field_ok(defmt::intern!("CFGR.CONT"), cfgr.cont().into(), 0);
    ok &= field_ok(defmt::intern!("CFGR.DMAEN"), cfgr.dmaen().into(), 1);
    ok &= field_ok(
        defmt::intern!("CFGR.DMACFG"),
        cfgr.dmacfg().to_bits().into(),
        Dmacfg::CIRCULAR.to_bits().into(),
    );
    ok &= field_ok(defmt::intern!("CR.ADSTART"), adc.cr().read().adstart().into(), 1);
    ok &= field_ok(defmt::intern!("CFGR2.ROVSE"), cfgr2.rovse().into(), 1);
    ok &= field_ok(
        defmt::intern!("CFGR2.OVSR"),
        cfgr2.ovsr().to_bits().into(),
        OversamplingRatio::RATIO16.to_bits().into(),
    );
    ok &= field_ok(
        defmt::intern!("CFGR2.OVSS"),
        cfgr2.ovss().to_bits().into(),
        OversamplingShift::SHIFT0.to_bits().into(),
    );
    ok &= field_ok(
        defmt::intern!("CFGR2.TROVS"),
        cfgr2.trovs().to_bits().into(),
        Trovs::AUTOMATIC.to_bits().into(),
    );
    ok &= field_ok(defmt::intern!("SQR1.L"), sqr1.l().into(), (N_SCAN - 1) as u32);
    for (rank, &ch) in SCAN_CHANNELS.iter().enumerate() {
        ok &= field_ok(defmt::intern!("SQR1.SQx"), sqr1.sq(rank).into(), ch.into());
        let want = if rank == 0 { DUMMY_SAMPLE_TIME } else { SAMPLE_TIME };
        let got = adc.smpr(ch as usize / 10).read().smp(ch as usize % 10);
        ok &= field_ok(defmt::intern!("SMPRx.SMPy"), got.to_bits().into(), want.to_bits().into());
    }
    let tim = timer.regs_basic();
    ok &= field_ok(
        defmt::intern!("TIM6_CR2.MMS"),
        tim.cr2().read().mms().to_bits().into(),
        Mms::UPDATE.to_bits().into(),
    );
    ok &= field_ok(defmt::intern!("TIM6_CR1.CEN"), tim.cr1().read().cen().into(), 1);
    let period = (tim.psc().read() as u64 + 1) * (tim.arr().read().arr() as u64 + 1);
    let achieved_mhz = timer.get_clock_frequency().0 as u64 * 1000 / period;
    let want_mhz = rate_hz as u64 * 1000;
    if achieved_mhz.abs_diff(want_mhz) * 1000 > want_mhz {
        defmt::error!(
            "ADC trigger read-back: TIM6 runs at {=u64} mHz, {=u32} Hz wanted",
            achieved_mhz,
            rate_hz
        );
        ok = false;
    }
    ok
}

/// The independent watchdog, running ([`start_watchdog`]).
pub struct WatchdogImpl(());

impl Watchdog for WatchdogImpl {
    fn feed(&mut self) {
        pac::IWDG.kr().write(|w| w.set_key(Key::RESET));
    }
}

/// Starts the independent watchdog with [`WATCHDOG_TIMEOUT_US`], before [`init`] (so that a
/// hang in the clocks', the ADC's or the record's bring-up resets too), after freezing it, TIM2
/// and TIM6 for a debugger's halts (DBGMCU_APB1FZR1 DBG_IWDG_STOP, DBG_TIM2_STOP,
/// DBG_TIM6_STOP; stm32-metapac 21 `peripherals/dbgmcu_l4.rs`). The sequence is RM0351 §32.3
/// "Software watchdog" with the window disabled, through stm32-metapac 21's
/// `peripherals/iwdg_v2.rs` (KR 0x00, PR 0x04, RLR 0x08, SR 0x0C): start (KR = 0xCCCC, which
/// also forces the LSI on, whatever RCC_CSR.LSION says), unlock (0x5555), PR, RLR, wait until SR
/// shows both updates done (bounded), reload (0xAAAA). embassy-stm32's `IndependentWatchdog`
/// needs the peripheral singleton that only `embassy_stm32::init` hands out, hence the registers.
pub fn start_watchdog() -> WatchdogImpl {
    pac::DBGMCU.apb1fzr1().modify(|w| {
        w.set_iwdg(true);
        w.set_tim2(true);
        w.set_tim6(true);
    });
    let iwdg = pac::IWDG;
    iwdg.kr().write(|w| w.set_key(Key::START));
    iwdg.kr().write(|w| w.set_key(Key::ENABLE));
    iwdg.pr().write(|w| w.set_pr(IWDG_PR));
    iwdg.rlr().write(|w| w.set_rl(IWDG_RELOAD));
    for _ in 0..IWDG_UPDATE_POLLS {
        if iwdg.sr().read().0 == 0 {
            break;
        }
    }
    iwdg.kr().write(|w| w.set_key(Key::RESET));
    WatchdogImpl(())
}

/// Reads the reset flags of RCC_CSR (RM0351 §6.4.29; stm32-metapac 21 `peripherals/rcc_l4.rs`,
/// `Csr`) and clears them (RMVF), so that the next boot sees only its own reset's flags.
fn take_reset_cause() -> ResetCause {
    let csr = pac::RCC.csr().read();
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    defmt::info!("RCC_CSR at boot: {=u32:#010x}", csr.0);
    ResetCause::from_rcc_csr(csr.0)
}

/// Field build: a panic is logged and resets the MCU.
#[cfg(not(feature = "debug-panic"))]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    // The location only: formatting the message would link `core::fmt` (about 5 KiB of flash).
    match info.location() {
        Some(l) => defmt::error!("panic at {=str}:{=u32}", l.file(), l.line()),
        None => defmt::error!("panic"),
    }
    cortex_m::peripheral::SCB::sys_reset()
}

/// Field build: a hard fault is logged and resets the MCU (cortex-m-rt's default handler loops).
#[cfg(not(feature = "debug-panic"))]
#[cortex_m_rt::exception]
unsafe fn HardFault(ef: &cortex_m_rt::ExceptionFrame) -> ! {
    defmt::error!("hard fault at pc {=u32:#010x}", ef.pc());
    cortex_m::peripheral::SCB::sys_reset()
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

/// Brings up clocks, USART1, TIM6 and ADC1 with DMA (the watchdog runs already:
/// [`start_watchdog`]).
pub fn init() -> Board {
    let reset_cause = take_reset_cause();
    let p = embassy_stm32::init(clocks());

    let mut uart_cfg = usart::Config::default();
    uart_cfg.baudrate = BAUD;
    let uart = Uart::new(p.USART1, p.PB7, p.PB6, p.DMA1_CH4, p.DMA1_CH5, Irqs, uart_cfg)
        .expect("USART1 configuration is valid");
    let (tx, rx) = uart.split();
    // Sized by the protocol (wire::LINK_RX_RING): it holds every request the host may keep
    // unanswered (wire::MAX_REQUESTS_IN_FLIGHT).
    let rx_buf = cortex_m::singleton!(: [u8; LINK_RX_RING] = [0; LINK_RX_RING]).expect("init runs once");
    let rx = rx.into_ring_buffered(rx_buf);

    let adc_cfg = AdcConfig {
        oversampling_ratio: Some(OversamplingRatio::RATIO16),
        oversampling_shift: Some(OversamplingShift::SHIFT0),
        oversampling_mode: Some((Rovsm::CONTINUED, Trovs::AUTOMATIC, true)),
        ..Default::default()
    };
    let mut adc = Adc::new_with_config(p.ADC1, adc_cfg);
    let mut vrefint = adc.enable_vrefint();
    // The temperature sensor's calibration: VDDA from VREFINT and the first temperature, read
    // once each (oversampled 16×; embassy's blocking read converts twice for the erratum).
    let mut sensor = adc.enable_temperature();
    let vref_sum = adc.blocking_read(&mut vrefint, TEMP_SAMPLE_TIME);
    let ts_sum = adc.blocking_read(&mut sensor, TEMP_SAMPLE_TIME);
    let cal = McuTempCal::new(
        read_system_u16(mcu_temp::TS_CAL1_ADDR),
        read_system_u16(mcu_temp::TS_CAL2_ADDR),
        read_system_u16(mcu_temp::VREFINT_CAL_ADDR),
        vref_sum as f32 / OVERSAMPLING,
    );
    let first_c = cal.map_or(f32::NAN, |c| c.temp_c(ts_sum as f32 / OVERSAMPLING));
    match cal {
        Some(c) => defmt::info!(
            "MCU temperature sensor: TS_CAL1 {=u16}, TS_CAL2 {=u16}, VDDA/3.0 V {=f32}, now {=f32} °C",
            c.ts_cal1,
            c.ts_cal2,
            c.vdda_ratio,
            first_c
        ),
        None => {
            defmt::error!("MCU temperature sensor: implausible factory calibration, temperature reads NaN")
        }
    }
    let dma_buf = cortex_m::singleton!(: [u16; 2 * MAX_BLOCK * N_SCAN] = [0; 2 * MAX_BLOCK * N_SCAN])
        .expect("init runs once");
    // Ranks as SCAN_CHANNELS says: the discarded conversion first.
    let sequence = [
        (AdcChannel::<ADC1>::degrade_adc(vrefint), DUMMY_SAMPLE_TIME),
        (p.PC5.degrade_adc(), SAMPLE_TIME),
        (p.PC4.degrade_adc(), SAMPLE_TIME),
        (p.PC3.degrade_adc(), SAMPLE_TIME),
    ];
    let mut adc = adc.into_ring_buffered(p.DMA1_CH1, dma_buf, Irqs, sequence.into_iter(), CONTINUOUS);
    // embassy-stm32 sets up continuous conversions on this ADC version; switch to one scan per
    // TIM6 trigger (CFGR CONT = 0, EXTEN = rising, EXTSEL = TIM6_TRGO; RM0351 §18.7.4).
    embassy_stm32::pac::ADC1.cfgr().modify(|w| {
        w.set_cont(false);
        w.set_exten(EXTEN_RISING);
        w.set_extsel(EXTSEL_TIM6_TRGO);
    });

    McuTemp::configure();

    let timer = Timer::new(p.TIM6);
    // TRGO on every update event (TIM6_CR2 MMS = 010, RM0351 §30.4.2).
    timer.regs_basic().cr2().modify(|w| w.set_mms(Mms::UPDATE));
    adc.start();
    McuTemp::start();
    if timer.get_clock_frequency().0 != TIM6_CLOCK_MHZ * 1_000_000 {
        defmt::error!("TIM6 clock is not {=u32} MHz: overrun counts will be wrong", TIM6_CLOCK_MHZ);
    }
    let mut clock = SampleClockImpl { timer, rate_hz: DEFAULT_RATE_HZ };
    // Starts TIM6 (the app reads the trigger configuration back when it builds the node).
    clock.set_rate(DEFAULT_RATE_HZ);

    Board {
        rx: LinkRxImpl(rx),
        tx: LinkTxImpl(tx),
        storage: Storage,
        source: SourceImpl { adc, temp: McuTemp { cal, last_c: first_c } },
        clock,
        reset_cause,
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
