//! File names the CPU196 board asks the monitor's file server for (`FileService::resolve`, a
//! THREAD open from the serial line): no panic, and a name it accepts never leads outside the
//! served folder, through `..`, an absolute path or a symbolic link.
#![no_main]

use std::os::unix::fs::symlink;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use buslab_served::cpu196::FileService;
use libfuzzer_sys::fuzz_target;

/// A served folder with a file, a subfolder, and links that stay inside or lead out.
fn served() -> &'static (FileService, PathBuf) {
    static SERVED: OnceLock<(FileService, PathBuf)> = OnceLock::new();
    SERVED.get_or_init(|| {
        // One folder per process (parallel jobs), and those of finished runs removed.
        let tmp = std::env::temp_dir();
        for old in std::fs::read_dir(&tmp).into_iter().flatten().flatten() {
            let name = old.file_name().to_string_lossy().into_owned();
            if let Some(pid) = name.strip_prefix("buslab-fuzz-files-")
                && !Path::new("/proc").join(pid).exists()
            {
                let _ = std::fs::remove_dir_all(old.path());
            }
        }
        let base = tmp.join(format!("buslab-fuzz-files-{}", std::process::id()));
        let root = base.join("root");
        let _ = std::fs::remove_dir_all(&base);
        std::fs::create_dir_all(root.join("sub/deeper")).unwrap();
        std::fs::write(base.join("secret"), b"outside").unwrap();
        std::fs::write(root.join("a.txt"), b"inside").unwrap();
        symlink("..", root.join("sub/up")).unwrap(); // back to the root: inside
        symlink("a.txt", root.join("link")).unwrap(); // inside
        symlink("../secret", root.join("out")).unwrap(); // outside
        symlink("/", root.join("slash")).unwrap(); // outside
        symlink("..", root.join("parent")).unwrap(); // outside
        symlink("../nowhere/x", root.join("dangling")).unwrap(); // outside, dangling
        let service = FileService::new(&root).unwrap();
        (service, root.canonicalize().unwrap())
    })
}

/// Where `path` really leads: its longest existing prefix with links followed, then the rest.
fn real(path: &Path) -> Option<PathBuf> {
    let mut probe = path.to_path_buf();
    let mut rest = Vec::new();
    while probe.symlink_metadata().is_err() {
        rest.push(probe.file_name()?.to_owned());
        probe = probe.parent()?.to_path_buf();
    }
    let mut real = probe.canonicalize().ok()?;
    for part in rest.iter().rev() {
        real.push(part);
    }
    Some(real)
}

fuzz_target!(|data: &[u8]| {
    let (service, root) = served();
    if let Ok(path) = service.resolve(data) {
        assert!(path.starts_with(root), "{path:?} is outside {root:?}");
        let real = real(&path).unwrap_or_else(|| panic!("{path:?} cannot be followed"));
        assert!(
            real.starts_with(root),
            "{path:?} leads to {real:?}, outside {root:?}"
        );
    }
});
