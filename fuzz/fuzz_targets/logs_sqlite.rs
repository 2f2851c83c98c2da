//! python-can SQLite databases (`sqlite::Reader`, `buslab play/dump` on a `.db` file): no
//! panic and the reader ends, whatever the file holds (any page, any table, any column type).
//! The bytes go to a file first: SQLite opens paths.
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use buslab_fuzz::logs::read_all;
use buslab_logs::sqlite::Reader;
use libfuzzer_sys::fuzz_target;

/// This process's database file (parallel jobs each have their own).
fn path() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        // In memory where there is a tmpfs: SQLite opens the file at every input.
        let shm = std::path::Path::new("/dev/shm");
        let dir = if shm.is_dir() {
            shm.to_path_buf()
        } else {
            std::env::temp_dir()
        };
        // The files of finished runs removed.
        for old in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
            let name = old.file_name().to_string_lossy().into_owned();
            if let Some(pid) = name
                .strip_prefix("buslab-fuzz-sqlite-")
                .and_then(|rest| rest.split('.').next())
                && !std::path::Path::new("/proc").join(pid).exists()
            {
                let _ = std::fs::remove_file(old.path());
            }
        }
        dir.join(format!("buslab-fuzz-sqlite-{}.db", std::process::id()))
    })
}

fuzz_target!(|data: &[u8]| {
    let path = path();
    std::fs::write(path, data).expect("writing the database file");
    // A journal left by an earlier input would be applied to this one.
    let _ = std::fs::remove_file(path.with_extension("db-journal"));
    if let Ok(reader) = Reader::open(path) {
        // A row takes at least a few bytes of a page, plus the end.
        read_all(reader, data.len() + 2);
    }
});
