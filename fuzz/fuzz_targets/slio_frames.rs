//! SLIO frames: requests as a SLIO reads them (`Request::parse`), replies as the master reads
//! them (`Reply::parse`) and register names as `buslab slio` takes them: no panic, and what
//! was accepted encodes back to frame data that parses the same.
#![no_main]

use buslab_slio::{Register, Reply, Request};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&first, data)) = data.split_first() else {
        return;
    };
    if let Ok(request) = Request::parse(first & 1 == 1, data)
        && first & 1 == 0
    {
        assert_eq!(Request::parse(false, &request.encode()), Ok(request));
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
