//! A port another client holds: `open_when_free` waits for it, within its patience.

use std::time::Duration;

use buslab_link::{LineSettings, SerialError, SerialLine};
use nix::pty::openpty;

#[test]
fn a_client_waits_for_a_port_another_one_holds_and_gets_it_when_freed() {
    let pty = openpty(None, None).unwrap();
    let path = nix::unistd::ttyname(&pty.slave).unwrap();
    let line = LineSettings::n81(9600);
    let holder = SerialLine::open(&path, line).unwrap();

    // No patience: the port is busy, and the error says so with the path.
    match SerialLine::open_when_free(&path, line, Duration::ZERO) {
        Err(e @ SerialError::Busy { .. }) => {
            assert!(e.to_string().contains(&path.display().to_string()), "{e}")
        }
        Err(e) => panic!("not busy: {e}"),
        Ok(_) => panic!("opened a port another client holds"),
    }

    // A client with patience gets it once the holder lets go (the ceiling only bounds a
    // failure).
    let waiter = {
        let path = path.clone();
        std::thread::spawn(move || {
            SerialLine::open_when_free(&path, line, Duration::from_secs(120)).map(|_| ())
        })
    };
    std::thread::sleep(Duration::from_millis(200));
    assert!(!waiter.is_finished(), "the waiter did not wait");
    drop(holder);
    waiter.join().unwrap().unwrap();
}

#[test]
fn a_port_that_does_not_exist_is_not_waited_for() {
    let err = SerialLine::open_when_free(
        std::path::Path::new("/nonexistent/buslab-port"),
        LineSettings::n81(9600),
        Duration::from_secs(120),
    )
    .err()
    .expect("opened a missing port");
    assert!(matches!(err, SerialError::Open { .. }), "{err}");
}
