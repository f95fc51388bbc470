//! SKR 2 board image (being written; built only with `--features board` for thumbv7em).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
use defmt_rtt as _;

#[cfg(target_os = "none")]
#[embassy_executor::main]
async fn main(_spawner: embassy_executor::Spawner) {
    let _p = embassy_stm32::init(Default::default());
    defmt::info!("skr2 up");
    loop {
        embassy_time::Timer::after_millis(1000).await;
    }
}

#[cfg(target_os = "none")]
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    cortex_m::asm::udf()
}

#[cfg(not(target_os = "none"))]
fn main() {}
