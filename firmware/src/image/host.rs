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

use super::{printer_now_us, Shared, UART_OUT, USB_OUT};

/// Pushes each port's pending host-link output to its pipe (USB, TFT UART), as far as the
/// pipe has room; the executive keeps the rest in that port's output ring.
pub(super) fn flush_output(p: &mut Printer) {
    let mut buf = [0u8; 128];
    for (port, pipe) in [(PortId::Usb, &USB_OUT), (PortId::Tft, &UART_OUT)] {
        loop {
            let room = pipe.free_capacity().min(buf.len());
            let n = p.read_output_on(port, buf.get_mut(..room).unwrap_or(&mut []));
            if n == 0 {
                break;
            }
            let _ = pipe.try_write(buf.get(..n).unwrap_or(&[]));
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

#[embassy_executor::task]
pub(super) async fn uart_task(uart: BufferedUart<'static>, printer: Shared) {
    use embedded_io_async::{Read, Write};
    let (mut tx, mut rx) = uart.split();
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
                        Ok(k) => {
                            let _ = tx.write_all(outbuf.get(..k).unwrap_or(&[])).await;
                        }
                        Err(_) => Timer::after_millis(1).await,
                    }
                }
            }
            Either::First(Err(_)) => {}
            Either::Second(n) => {
                let _ = tx.write_all(outbuf.get(..n).unwrap_or(&[])).await;
            }
        }
    }
}
