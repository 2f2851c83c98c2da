//! The JSON bodies of the device panels' writes (`buslab_web::device_request`: `POST
//! /api/slio`, `/api/zelle`, `/api/cpu196` in `buslab lab`). The first byte chooses which;
//! the rest is the body.
//!
//! Besides no panic: a refusal is a client error (4xx) whose reason names the refused value;
//! an accepted body gives an order that, written as a body again, reads back as the same
//! order, within the limits the panel promises (a RAM view of 1..512 bytes, a measurement of
//! 1..100 blocks lasting 10 minutes at most, bank and configuration 0..7, a demo board's
//! switch 0..3 and potentiometer 0..5 V).
#![no_main]

use buslab_web::ApiError;
use buslab_web::device_request::{
    Cpu196Order, DeviceRequestError, MAX_MEASUREMENT, SlioOrder, ZelleOrder, cpu196_request,
    slio_request, zelle_request,
};
use buslab_web::devices::zelle::{MAX_CHUNKS, MAX_RAM_VIEW, run_time};
use libfuzzer_sys::fuzz_target;

fn refused(e: DeviceRequestError) {
    // What the refusal must name, beyond its reason.
    let named = match &e {
        DeviceRequestError::Json { example, .. } => example.to_string(),
        DeviceRequestError::SlioNumber(text) => format!("{text:?}"),
        DeviceRequestError::Switch(bad) => format!("switch {}", bad.0),
        DeviceRequestError::Volts(volts) => format!("volts {volts}"),
        DeviceRequestError::RamLength(len) => len.to_string(),
        DeviceRequestError::Series { channels, .. }
        | DeviceRequestError::EmptyMeasurement { channels, .. } => format!("{channels:?}"),
        DeviceRequestError::Chunks(chunks) => chunks.to_string(),
        DeviceRequestError::TooLong(lasts) => lasts.as_secs().to_string(),
        DeviceRequestError::BankOrConfig { bank, config } => {
            format!("bank {bank}, config {config}")
        }
    };
    let api = ApiError::from(e);
    assert!(api.status.is_client_error(), "{api:?}");
    assert!(
        api.reason.contains(&named),
        "{:?} does not name {named:?}",
        api.reason
    );
}

fuzz_target!(|data: &[u8]| {
    let Some((&which, body)) = data.split_first() else {
        return;
    };
    match which % 3 {
        0 => match slio_request(body) {
            Ok(order) => {
                match order {
                    SlioOrder::Switch { switch, .. } => assert!(switch.number() <= 3),
                    SlioOrder::Pot { volts, .. } => assert!((0.0..=5.0).contains(&volts.get())),
                    _ => {}
                }
                let json = order.to_json();
                match slio_request(json.as_bytes()) {
                    Ok(again) => assert_eq!(again, order, "written as {json}"),
                    Err(e) => panic!("{order:?} written as {json} is refused: {e}"),
                }
            }
            Err(e) => refused(e),
        },
        1 => match zelle_request(body) {
            Ok(order) => {
                match order {
                    ZelleOrder::Ram { len } => assert!((1..=MAX_RAM_VIEW).contains(&len)),
                    ZelleOrder::Measure { params, chunks } => {
                        assert!((1..=MAX_CHUNKS).contains(&chunks));
                        assert!(params.cycles > 0 && !params.channels().is_empty());
                        assert!(run_time(&params, chunks) <= MAX_MEASUREMENT);
                    }
                    ZelleOrder::Stop => {}
                }
                let json = order.to_json();
                match zelle_request(json.as_bytes()) {
                    Ok(again) => assert_eq!(again, order, "written as {json}"),
                    Err(e) => panic!("{order:?} written as {json} is refused: {e}"),
                }
            }
            Err(e) => refused(e),
        },
        _ => match cpu196_request(body) {
            Ok(order) => {
                if let Cpu196Order::Start { bank, config } = order {
                    assert!(bank <= 7 && config <= 7);
                }
                let json = order.to_json();
                match cpu196_request(json.as_bytes()) {
                    Ok(again) => assert_eq!(again, order, "written as {json}"),
                    Err(e) => panic!("{order:?} written as {json} is refused: {e}"),
                }
            }
            Err(e) => refused(e),
        },
    }
});
