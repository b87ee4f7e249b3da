//! Any bytes as the saved window state: the state (which encodes back to
//! the same bytes it was read from, up to its length) or a typed error.
#![no_main]

use libfuzzer_sys::fuzz_target;
use snowpack::low_level::snow::saved::SavedWindow;

fuzz_target!(|data: &[u8]| {
    if let Ok(state) = SavedWindow::decode(data, std::path::Path::new("fuzz.state")) {
        let bytes = state.encode();
        assert_eq!(&data[..bytes.len()], &bytes[..], "the state does not encode to what it was read from");
    }
});
