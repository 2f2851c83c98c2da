//! What `buslab web` reads of a request before anything else: the `Host` header (and an
//! absolute-form target's authority) and a write's `Origin` header, checked against the
//! allow-list (`HostGuard`); the `--allow-host` names themselves. The first byte chooses which;
//! the rest is the input.
//!
//! Besides no panic: a refusal is a 4xx with a reason; an accepted host names an IP address,
//! `localhost` or an allowed name; an allowed name, once accepted, is answered to.
#![no_main]

use buslab_web::guard::HostGuard;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&which, input)) = data.split_first() else {
        return;
    };
    let guard = HostGuard::new(&["bench.lab".to_string()]).unwrap();
    match which % 3 {
        0 => match guard.check_host(Some(input), which & 0x80 != 0) {
            Ok(()) => {
                let text = std::str::from_utf8(input).expect("an accepted Host is text");
                assert!(!text.contains(['@', '/', ' ']), "{text:?}");
            }
            Err(e) => {
                assert!(e.status.is_client_error(), "{e:?}");
                assert!(e.reason.contains("--allow-host"), "{}", e.reason);
            }
        },
        1 => match guard.check_origin(input) {
            Ok(()) => {
                let text = std::str::from_utf8(input).expect("an accepted Origin is text");
                assert!(
                    text.starts_with("http://") || text.starts_with("https://"),
                    "{text:?}"
                );
            }
            Err(e) => assert_eq!(e.status.as_u16(), 403, "{e:?}"),
        },
        _ => {
            let Ok(name) = std::str::from_utf8(input) else {
                return;
            };
            if let Ok(guard) = HostGuard::new(&[name.to_string()]) {
                // An IPv6 address goes into a Host header in brackets (given with or without).
                let host = if name.contains(':') && !name.starts_with('[') {
                    format!("[{name}]")
                } else {
                    name.to_string()
                };
                assert!(guard.allows(&host), "{name:?} accepted but not answered to");
                assert!(
                    guard.check_host(Some(host.as_bytes()), true).is_ok(),
                    "{host:?}"
                );
            }
        }
    }
});
