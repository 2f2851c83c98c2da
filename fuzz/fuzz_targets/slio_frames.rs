//! SLIO frames: requests as a SLIO reads them (`Request::parse`), replies as the master reads
//! them (`Reply::parse`) and register names as `buslab slio` takes them: no panic, only 3-byte
//! data frames (or remote frames) are requests, and what was accepted encodes back to 3 bytes
//! that parse the same.
#![no_main]

use buslab_slio::{Register, Reply, Request};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&first, data)) = data.split_first() else {
        return;
    };
    if let Ok(request) = Request::parse(first & 1 == 1, data) {
        // Whatever a SLIO takes has a 3-byte frame (a read of a writable register does not
        // exist), which it takes back the same.
        let bytes = request.data().expect("a parsed request has its 3 bytes");
        assert_eq!(Request::parse(false, &bytes), Ok(request));
        if first & 1 == 0 {
            assert_eq!(data.len(), 3);
        }
    }
    if let Ok(reply) = Reply::parse(data) {
        assert_eq!(Reply::parse(&reply.encode()), Ok(reply));
    }
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(register) = text.parse::<Register>()
    {
        assert_eq!(
            register.to_string().parse::<Register>().ok(),
            Some(register)
        );
    }
});
