//! The cell's fixed line and its timing.

use buslab_device::{LineSettings, Nanos};

/// The cell's line: 9600 baud, 8 data bits, no parity, 2 stop bits.
pub const LINE: LineSettings = LineSettings::n82(9600);

/// One character on the line: 11 bit-times at 9600 baud.
pub const BYTE_NS: Nanos = LINE.byte_time();

/// One millisecond.
pub const MS: Nanos = Nanos::from_millis(1);

/// How long the OS sets up its address pointer after commands 1, 2, 3 and 5. The seed asks the
/// host to pause this long before sending more.
pub const SETUP_NS: Nanos = MS;

/// One A/D conversion of a measurement series. The seed's "interval minus number of channels"
/// means each conversion takes about a millisecond of the interval. Direct readings (commands 4
/// and 7) take no time of their own: the seed says their function ends within the two stop
/// bits of the request.
pub const CONVERSION_NS: Nanos = MS;

/// The gap the seed asks for between the ten reset zeros.
pub const RESET_GAP_NS: Nanos = Nanos::from_millis(2);

/// START key hold times after a reset, by the seed: about 1 s selects measure mode, about 3 s
/// program mode, about 5 s the ready state. A shorter press leaves the stored mode alone.
pub const KEY_HOLD_MEASURE_NS: Nanos = Nanos::from_secs(1);
/// See [`KEY_HOLD_MEASURE_NS`].
pub const KEY_HOLD_PROGRAM_NS: Nanos = Nanos::from_secs(3);
/// See [`KEY_HOLD_MEASURE_NS`]. The OS stops timing here even if the key is still held.
pub const KEY_HOLD_READY_NS: Nanos = Nanos::from_secs(5);

/// How often the cell asks to be run while a program runs: its output is known only once the
/// core has run (one character time behind the line), so the host polls it this often.
pub const PROGRAM_POLL_NS: Nanos = MS;
