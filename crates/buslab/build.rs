//! The `buslab` binary's debug sections are compressed (zlib) by the linker in release builds:
//! the line tables stay in the binary (backtraces, perf and valgrind read them compressed) at
//! a third of their size (docs/build.md).

fn main() {
    println!("cargo::rerun-if-changed=build.rs");
    let release = std::env::var("PROFILE").as_deref() == Ok("release");
    let linux = std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux");
    if release && linux {
        println!("cargo::rustc-link-arg-bins=-Wl,--compress-debug-sections=zlib");
    }
}
