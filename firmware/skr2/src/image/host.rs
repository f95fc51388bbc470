//! The host ports: USB CDC-ACM and the TFT header's UART. Their tasks move bytes between the
//! wire and the pipes of `channels`; the motion task (the executive's owner) takes the bytes
//! in with flow control ([`take_input`]: what `Printer::receive_on` does not take waits in
//! [`Carry`] and holds the pipe back) and pushes the answers out ([`flush_output`]).

use embassy_futures::join::join3;
use embassy_futures::select::{select, Either};
use embassy_stm32::peripherals;
use embassy_stm32::usart::BufferedUart;
use embassy_stm32::usb::Driver;
use embassy_time::Timer;
use embassy_usb::class::cdc_acm::CdcAcmClass;
use embassy_usb::UsbDevice;
use firmware::link::PortId;
use firmware::printer::Printer;

use super::channels::{SESSIONS, TFT_IN, TFT_OUT, USB_IN, USB_OUT};
use super::{printer_now_us, Irqs, UART_BAUD, UART_RX_BUF, UART_TX_BUF};
use embassy_stm32::usart::Config as UartConfig;
use embassy_stm32::usb;
use embassy_usb::class::cdc_acm::State as CdcState;
use static_cell::StaticCell;

/// The USB CDC-ACM device on the board's USB port (VID 0x0483 / PID 0x5740, as the STM32's own
/// virtual COM port), its control and descriptor buffers in statics.
pub(super) fn usb_port(
    (usb_p, dp, dm): (
        embassy_stm32::Peri<'static, peripherals::USB_OTG_FS>,
        embassy_stm32::Peri<'static, peripherals::PA12>,
        embassy_stm32::Peri<'static, peripherals::PA11>,
    ),
) -> (
    UsbDevice<'static, Driver<'static, peripherals::USB_OTG_FS>>,
    CdcAcmClass<'static, Driver<'static, peripherals::USB_OTG_FS>>,
) {
    static EP_OUT: StaticCell<[u8; 256]> = StaticCell::new();
    static CONFIG_DESC: StaticCell<[u8; 256]> = StaticCell::new();
    static BOS_DESC: StaticCell<[u8; 256]> = StaticCell::new();
    static CONTROL: StaticCell<[u8; 64]> = StaticCell::new();
    static CDC_STATE: StaticCell<CdcState> = StaticCell::new();
    let mut usb_config = usb::Config::default();
    usb_config.vbus_detection = false;
    let driver = Driver::new_fs(usb_p, Irqs, dp, dm, EP_OUT.init([0; 256]), usb_config);
    let mut dev = embassy_usb::Config::new(0x0483, 0x5740);
    dev.manufacturer = Some("pause firmware");
    dev.product = Some("SKR 2 printer");
    dev.serial_number = Some("skr2");
    dev.max_power = 100;
    dev.max_packet_size_0 = 64;
    let mut builder = embassy_usb::Builder::new(
        driver,
        dev,
        CONFIG_DESC.init([0; 256]),
        BOS_DESC.init([0; 256]),
        &mut [],
        CONTROL.init([0; 64]),
    );
    let cdc = CdcAcmClass::new(&mut builder, CDC_STATE.init(CdcState::new()), 64);
    (builder.build(), cdc)
}

/// The TFT header's UART (USART1, [`UART_BAUD`]), buffered both ways.
pub(super) fn tft_port(
    (uart_p, rx, tx): (
        embassy_stm32::Peri<'static, peripherals::USART1>,
        embassy_stm32::Peri<'static, peripherals::PA10>,
        embassy_stm32::Peri<'static, peripherals::PA9>,
    ),
) -> Result<BufferedUart<'static>, embassy_stm32::usart::ConfigError> {
    static UART_TX: StaticCell<[u8; UART_TX_BUF]> = StaticCell::new();
    static UART_RX: StaticCell<[u8; UART_RX_BUF]> = StaticCell::new();
    let mut ucfg = UartConfig::default();
    ucfg.baudrate = UART_BAUD;
    BufferedUart::new(
        uart_p,
        rx,
        tx,
        UART_TX.init([0; UART_TX_BUF]),
        UART_RX.init([0; UART_RX_BUF]),
        Irqs,
        ucfg,
    )
}

/// Bytes taken from a port's pipe that the executive has not taken yet (its line assembler
/// was full): offered again first, and no more is read from the pipe meanwhile.
pub(super) struct Carry {
    buf: [u8; 64],
    start: usize,
    end: usize,
}

impl Carry {
    pub(super) const fn new() -> Self {
        Self {
            buf: [0; 64],
            start: 0,
            end: 0,
        }
    }
}

/// Offers each port's waiting bytes to the executive, as far as it takes them (at most four
/// pipe reads a port per call, so one tick stays short).
pub(super) fn take_input(p: &mut Printer, carry: &mut [Carry; 2]) {
    let now_us = printer_now_us();
    for (c, (port, pipe)) in carry
        .iter_mut()
        .zip([(PortId::Usb, &USB_IN), (PortId::Tft, &TFT_IN)])
    {
        for _ in 0..4 {
            if c.start == c.end {
                match pipe.try_read(&mut c.buf) {
                    Ok(n) => (c.start, c.end) = (0, n),
                    Err(_) => break,
                }
            }
            let data = c.buf.get(c.start..c.end).unwrap_or(&[]);
            let taken = p.receive_on(port, data, now_us);
            c.start += taken;
            if c.start < c.end {
                // The executive is full: the rest waits here.
                break;
            }
        }
    }
}

/// Session changes the port tasks saw (DTR, USB reset), told to the executive.
pub(super) fn take_sessions(p: &mut Printer) {
    while let Ok((port, open)) = SESSIONS.try_receive() {
        p.port_session(port, open, printer_now_us());
    }
}

/// Pushes each port's pending host-link output to its pipe; returns whether any was pushed (USB, TFT UART), as far as the
/// pipe has room; the executive keeps the rest in that port's output ring.
///
/// `Pipe::try_write` writes only up to the end of the pipe's ring buffer (its contiguous free
/// part), so a chunk that straddles the wrap takes two writes; taking one and dropping the
/// rest lost the middle of lines (seen on the emulated board: a notice cut after 12 bytes).
pub(super) fn flush_output(p: &mut Printer) -> bool {
    let mut buf = [0u8; 128];
    let mut wrote = false;
    for (port, pipe) in [(PortId::Usb, &USB_OUT), (PortId::Tft, &TFT_OUT)] {
        loop {
            let room = pipe.free_capacity().min(buf.len());
            let n = p.read_output_on(port, buf.get_mut(..room).unwrap_or(&mut []));
            if n == 0 {
                break;
            }
            wrote = true;
            let mut chunk = buf.get(..n).unwrap_or(&[]);
            while !chunk.is_empty() {
                match pipe.try_write(chunk) {
                    Ok(k) => chunk = chunk.get(k..).unwrap_or(&[]),
                    Err(_) => {
                        // Cannot happen: `room` was free.
                        defmt::error!("host output: {=usize} bytes lost", chunk.len());
                        break;
                    }
                }
            }
        }
    }
    wrote
}

/// Answers still on their way to a port task.
pub(super) fn output_waiting() -> bool {
    !USB_OUT.is_empty() || !TFT_OUT.is_empty()
}

#[embassy_executor::task]
pub(super) async fn usb_task(
    mut dev: UsbDevice<'static, Driver<'static, peripherals::USB_OTG_FS>>,
) {
    dev.run().await
}

#[embassy_executor::task]
pub(super) async fn cdc_task(
    class: CdcAcmClass<'static, Driver<'static, peripherals::USB_OTG_FS>>,
) {
    // The session (docs/frontend.md, "A session that ends while paused"): DTR set when a host
    // opens the port, cleared when it closes it; a USB reset or unplug ends it too.
    let (mut tx, mut rx, control) = class.split_with_control();
    let line_state = async {
        let mut open = false;
        loop {
            control.control_changed().await;
            let dtr = control.dtr();
            if dtr != open {
                open = dtr;
                SESSIONS.send((PortId::Usb, dtr)).await;
            }
        }
    };
    let receive = async {
        let mut buf = [0u8; 64];
        loop {
            rx.wait_connection().await;
            while let Ok(n) = rx.read_packet(&mut buf).await {
                // Flow control: while the pipe is full this waits, the next packet is not
                // read, and the endpoint NAKs the host.
                USB_IN.write_all(buf.get(..n).unwrap_or(&[])).await;
            }
            // The endpoint went down (USB reset or unplug): the session ended.
            SESSIONS.send((PortId::Usb, false)).await;
        }
    };
    let send = async {
        let mut buf = [0u8; 64];
        loop {
            tx.wait_connection().await;
            loop {
                let n = USB_OUT.read(&mut buf).await;
                let data = buf.get(..n).unwrap_or(&[]);
                if tx.write_packet(data).await.is_err() {
                    break;
                }
            }
        }
    };
    join3(receive, send, line_state).await;
}

/// The TFT UART's transmit side, written so that embassy-stm32 0.6's `BufferedUartTx` never
/// waits forever: its `write` returns `Pending` **without registering a waker** when the
/// whole slice does not fit in the free part of its buffer (`usart/buffered.rs`,
/// `BufferedUartTx::write`), and nothing wakes the task again (found on the emulated board:
/// transmission stopped for good in the middle of M115's capability list, the driver's buffer
/// empty, TXEIE off). Its `flush` is no reliable way to know the buffer empty either: it
/// waits for `tx_done`, which the interrupt also sets on a transmission-complete flag seen
/// between two bytes while more are queued (the port stopped again at start-up on the
/// emulated board after a 0.6 s settings load). So each write is given [`TX_RETRY_MS`]: a
/// write still pending then is dropped and made again, and the new one looks at the free
/// room afresh (the driver keeps nothing of a pending write: it copies only once the whole
/// slice fits). Chunks are at most [`TX_CHUNK`] bytes, so one fits as soon as the interrupt
/// has sent that much.
struct TftTx {
    tx: embassy_stm32::usart::BufferedUartTx<'static>,
}

/// Largest slice handed to the driver at once (an eighth of its buffer: 5.6 ms of line time
/// at 115200 Bd).
const TX_CHUNK: usize = UART_TX_BUF / 8;
/// How long a write may stay pending before it is made again, ms (a chunk's line time).
const TX_RETRY_MS: u64 = 6;

impl TftTx {
    async fn send(&mut self, data: &[u8]) {
        use embassy_time::{with_timeout, Duration};
        use embedded_io_async::Write;
        let mut rest = data;
        while !rest.is_empty() {
            let n = rest.len().min(TX_CHUNK);
            let chunk = rest.get(..n).unwrap_or(&[]);
            match with_timeout(Duration::from_millis(TX_RETRY_MS), self.tx.write(chunk)).await {
                Ok(Ok(k)) => rest = rest.get(k..).unwrap_or(&[]),
                // A driver error (none on transmit today): the rest of the answer is lost.
                Ok(Err(_)) => return,
                // Pending without a waker, or the line is slow: ask again.
                Err(_) => {}
            }
        }
    }
}

#[embassy_executor::task]
pub(super) async fn uart_task(uart: BufferedUart<'static>) {
    use embedded_io_async::Read;
    let (tx, mut rx) = uart.split();
    let mut tx = TftTx { tx };
    let mut inbuf = [0u8; 64];
    let mut outbuf = [0u8; 64];
    loop {
        match select(rx.read(&mut inbuf), TFT_OUT.read(&mut outbuf)).await {
            Either::First(Ok(n)) => {
                // Port 1: its own line assembler, line numbers and `ok`s. While the pipe is
                // full the rest waits (the UART's RX buffer holds what arrives meanwhile) and
                // the answers keep flowing.
                let mut data = inbuf.get(..n).unwrap_or(&[]);
                while !data.is_empty() {
                    match TFT_IN.try_write(data) {
                        Ok(k) => data = data.get(k..).unwrap_or(&[]),
                        Err(_) => match TFT_OUT.try_read(&mut outbuf) {
                            Ok(k) => tx.send(outbuf.get(..k).unwrap_or(&[])).await,
                            Err(_) => Timer::after_millis(1).await,
                        },
                    }
                }
            }
            Either::First(Err(_)) => {}
            Either::Second(n) => tx.send(outbuf.get(..n).unwrap_or(&[])).await,
        }
    }
}
