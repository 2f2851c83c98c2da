//! Opening buses by URL through the registry.

use std::io::{Read, Write};
use std::net::TcpListener;

use buslab_backends::{BACKENDS, OpenError, open};

#[test]
fn every_scheme_has_one_backend() {
    let schemes: Vec<&str> = BACKENDS.iter().map(|b| b.scheme).collect();
    assert_eq!(
        schemes,
        [
            "socketcand",
            "socketcan",
            "slcan",
            "cannelloni",
            "cannelloni+tcp",
            "mqtt",
            "mqtts"
        ]
    );
    for b in BACKENDS {
        assert!(b.syntax.starts_with(b.scheme), "{}", b.syntax);
    }
}

#[test]
fn devices_that_cannot_be_opened_are_named_with_a_hint() {
    // This machine's kernel may lack SocketCAN (EAFNOSUPPORT) or have it (ENODEV): either way
    // the error names the URL and says what to do.
    let err = open("socketcan:nosuchcan9")
        .err()
        .expect("no such interface");
    assert!(matches!(err, OpenError::SocketCan { .. }), "{err:?}");
    let text = err.to_string();
    assert!(
        text.starts_with("cannot open socketcan:nosuchcan9: "),
        "{text}"
    );
    assert!(
        text.contains("ip link add dev nosuchcan9 type vcan")
            || text.contains("this kernel has no SocketCAN"),
        "{text}"
    );
    let err = open("slcan:/nonexistent/ttyACM0?bitrate=500000")
        .err()
        .unwrap();
    assert!(matches!(err, OpenError::Slcan { .. }), "{err:?}");
    assert!(
        err.to_string()
            .starts_with("cannot open slcan:/nonexistent/ttyACM0?bitrate=500000: cannot open serial port /nonexistent/ttyACM0"),
        "{err}"
    );
    // A bad URL is named before anything is opened.
    let err = open("slcan:/dev/x?speed=1").err().unwrap();
    assert!(matches!(err, OpenError::Url(_)), "{err:?}");
}

#[test]
fn a_refused_connection_suggests_starting_a_bus() {
    // A port nobody listens on: bound, then closed.
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let err = open(&format!("socketcand://127.0.0.1:{port}/vcan0"))
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.starts_with(&format!(
            "cannot join socketcand://127.0.0.1:{port}/vcan0: "
        )),
        "{err}"
    );
    assert!(
        err.ends_with("start a bus with `buslab bus serve` or `buslab lab`)"),
        "{err}"
    );
}

#[test]
fn a_plain_socketcand_opens_without_admin() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let server = std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        s.write_all(b"< hi >").unwrap();
        let mut buf = [0u8; 256];
        let mut seen = String::new();
        // open, rawmode, buslab_ext: as socketcand answers them.
        for answer in ["< ok >", "< ok >", "< error unknown command >"] {
            let n = s.read(&mut buf).unwrap();
            seen.push_str(std::str::from_utf8(&buf[..n]).unwrap());
            s.write_all(answer.as_bytes()).unwrap();
        }
        let _ = s.read(&mut buf);
        seen
    });
    let mut bus = open(&format!("socketcand://{addr}/can1")).unwrap();
    assert!(bus.admin().is_none());
    assert_eq!(bus.channel_info(), format!("socketcand://{addr}/can1"));
    drop(bus);
    assert_eq!(
        server.join().unwrap(),
        "< open can1 >< rawmode >< buslab_ext >"
    );
}
