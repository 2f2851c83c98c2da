//! `buslab.toml` (`buslab_config::load_text`: the file's text, then `--set KEY=VALUE`). The
//! first byte chooses: even, the rest is the file; odd, each line of the rest is a `--set`.
//!
//! Besides no panic: an accepted configuration written as the wizard writes it
//! (`render_file`) loads to the same configuration and writes the same file again, and
//! `config show` prints it.
#![no_main]

use std::path::Path;

use buslab_config::{Found, load_text, render_file, render_show};
use buslab_fuzz::text;
use libfuzzer_sys::fuzz_target;

fn from_file(text: &str) -> Result<buslab_config::Loaded, buslab_config::ConfigError> {
    load_text(
        Some((Path::new("buslab.toml"), Found::CommandLine, text)),
        &|_| None,
        &[],
    )
}

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else {
        return;
    };
    let Some(input) = text(rest) else { return };
    let loaded = if which % 2 == 0 {
        from_file(input)
    } else {
        let sets: Vec<String> = input.lines().map(str::to_string).collect();
        load_text(None, &|_| None, &sets)
    };
    let Ok(loaded) = loaded else { return };
    let _ = render_show(&loaded);
    let written = render_file(&loaded.settings);
    match from_file(&written) {
        Ok(again) => {
            // The wizard writes only the controller keys that differ from the chip's
            // defaults: a key given at its default is no longer applied, the rest is equal.
            let (mut a, mut b) = (again.config.clone(), loaded.config.clone());
            let (parts_again, parts_before) =
                (a.controller_settings.parts(), b.controller_settings.parts());
            assert!(
                parts_again.iter().all(|p| parts_before.contains(p)),
                "{written}\napplies {parts_again:?}, more than {parts_before:?}"
            );
            a.controller_settings = Default::default();
            b.controller_settings = Default::default();
            assert!(a == b, "{written}\nloads differently");
            assert_eq!(
                render_file(&again.settings),
                written,
                "written again differently"
            );
        }
        Err(e) => panic!("the written file does not load: {e}\n{written}"),
    }
});
