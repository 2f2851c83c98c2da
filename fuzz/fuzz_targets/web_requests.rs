//! What the web server reads from a request besides HTTP itself (axum and hyper parse that):
//! the query of `/api/state` and `/api/events` (read by `serde_urlencoded` as axum's `Query`
//! does, then `ViewQuery::checked`), the JSON bodies of `/api/send` and `/api/fault`, and the
//! `X-Buslab-Token` header. The first byte chooses which; the rest is the input.
//!
//! Besides no panic: a refusal is a 4xx with a reason; an accepted filter prints as text that
//! parses to the same filter, an accepted frame likewise; a chart window is 1 s..10 min; a
//! fault lasts 1 ms..1 h or until repaired; the token is accepted exactly when it is the
//! server's.
#![no_main]

use std::time::Duration;

use buslab_can::Frame;
use buslab_fuzz::assert_reparses;
use buslab_view::LogFilter;
use buslab_web::ApiError;
use buslab_web::request::{
    MAX_FAULT_MS, MAX_STATE_LOG, MAX_WINDOW, ViewQuery, check_token, fault_request, send_request,
};
use libfuzzer_sys::fuzz_target;

fn refused(e: &ApiError) {
    assert!(e.status.is_client_error(), "{e:?}");
    assert!(!e.reason.trim().is_empty(), "a refusal without a reason");
}

fuzz_target!(|data: &[u8]| {
    let Some((&which, input)) = data.split_first() else {
        return;
    };
    match which % 4 {
        0 => {
            let Ok(query) = serde_urlencoded::from_bytes::<ViewQuery>(input) else {
                return;
            };
            match query.checked() {
                Ok(view) => {
                    assert!(view.frames <= MAX_STATE_LOG);
                    assert!(
                        (Duration::from_secs(1)..=MAX_WINDOW).contains(&view.window),
                        "{:?}",
                        view.window
                    );
                    assert_reparses(
                        &view.filter,
                        &view.filter.to_string(),
                        str::parse::<LogFilter>,
                    );
                }
                Err(e) => refused(&e),
            }
        }
        1 => match send_request(input) {
            Ok(frame) => assert_reparses(&frame, &frame.to_string(), str::parse::<Frame>),
            Err(e) => refused(&e),
        },
        2 => match fault_request(input) {
            Ok(order) => {
                if let Some(d) = order.lasting {
                    assert!(
                        (Duration::from_millis(1)..=Duration::from_millis(MAX_FAULT_MS))
                            .contains(&d),
                        "{d:?}"
                    );
                }
                let name = order.fault.name();
                assert!(
                    ["cut", "noise", "flip", "disconnect", "stuck"].contains(&name),
                    "{name}"
                );
            }
            Err(e) => refused(&e),
        },
        _ => {
            // The server's token, a NUL, the header's bytes (no NUL: no header at all).
            let (expected, given) = match input.iter().position(|&b| b == 0) {
                Some(i) => (&input[..i], Some(&input[i + 1..])),
                None => (input, None),
            };
            let Ok(expected) = std::str::from_utf8(expected) else {
                return;
            };
            let expected = (!expected.is_empty()).then_some(expected);
            match check_token(expected, given) {
                Ok(()) => assert_eq!(expected.map(str::as_bytes), given),
                Err(e) => {
                    refused(&e);
                    assert!(expected.is_none() || given != expected.map(str::as_bytes));
                }
            }
        }
    }
});
