//! The host ports: USB CDC-ACM and the TFT header's UART, each feeding `Printer::receive_on`
//! with flow control, and the executive's output pushed to each port's pipe.

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

use super::{printer_now_us, Shared, UART_OUT, UART_TX_BUF, USB_OUT};

/// Pushes each port's pending host-link output to its pipe (USB, TFT UART), as far as the
/// pipe has room; the executive keeps the rest in that port's output ring.
///
/// `Pipe::try_write` writes only up to the end of the pipe's ring buffer (its contiguous free
/// part), so a chunk that straddles the wrap takes two writes; taking one and dropping the
/// rest lost the middle of lines (seen on the emulated board: a notice cut after 12 bytes).
pub(super) fn flush_output(p: &mut Printer) {
    let mut buf = [0u8; 128];
    for (port, pipe) in [(PortId::Usb, &USB_OUT), (PortId::Tft, &UART_OUT)] {
        loop {
            let room = pipe.free_capacity().min(buf.len());
            let n = p.read_output_on(port, buf.get_mut(..room).unwrap_or(&mut []));
            if n == 0 {
                break;
            }
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
    printer: Shared,
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
                printer
                    .borrow_mut()
                    .port_session(PortId::Usb, dtr, printer_now_us());
            }
        }
    };
    let receive = async {
        let mut buf = [0u8; 64];
        loop {
            rx.wait_connection().await;
            while let Ok(n) = rx.read_packet(&mut buf).await {
                // Flow control: bytes the printer cannot take yet are offered again; the
                // next packet is not read meanwhile, so the endpoint NAKs the host.
                let mut data = buf.get(..n).unwrap_or(&[]);
                loop {
                    let taken =
                        printer
                            .borrow_mut()
                            .receive_on(PortId::Usb, data, printer_now_us());
                    data = data.get(taken..).unwrap_or(&[]);
                    if data.is_empty() {
                        break;
                    }
                    Timer::after_millis(1).await;
                }
            }
            // The endpoint went down (USB reset or unplug): the session ended.
            printer
                .borrow_mut()
                .port_session(PortId::Usb, false, printer_now_us());
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
pub(super) async fn uart_task(uart: BufferedUart<'static>, printer: Shared) {
    use embedded_io_async::Read;
    let (tx, mut rx) = uart.split();
    let mut tx = TftTx { tx };
    let mut inbuf = [0u8; 64];
    let mut outbuf = [0u8; 64];
    loop {
        match select(rx.read(&mut inbuf), UART_OUT.read(&mut outbuf)).await {
            Either::First(Ok(n)) => {
                // Port 1: its own line assembler, line numbers and `ok`s. Bytes not taken
                // are offered again (the UART's RX buffer holds the rest meanwhile), while
                // the answers keep flowing.
                let mut data = inbuf.get(..n).unwrap_or(&[]);
                loop {
                    let taken =
                        printer
                            .borrow_mut()
                            .receive_on(PortId::Tft, data, printer_now_us());
                    data = data.get(taken..).unwrap_or(&[]);
                    if data.is_empty() {
                        break;
                    }
                    match UART_OUT.try_read(&mut outbuf) {
                        Ok(k) => tx.send(outbuf.get(..k).unwrap_or(&[])).await,
                        Err(_) => Timer::after_millis(1).await,
                    }
                }
            }
            Either::First(Err(_)) => {}
            Either::Second(n) => tx.send(outbuf.get(..n).unwrap_or(&[])).await,
        }
    }
}
