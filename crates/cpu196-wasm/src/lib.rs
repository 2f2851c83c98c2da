//! CPU196 user programs a user writes and flashes (issue 31): WebAssembly modules stored in the
//! board's flash, run by wasmi (an interpreter: no JIT, deterministic, fuel-metered) behind the
//! kernel's hooks ([`buslab_cpu196::program::UserProgram`]).
//!
//! [`abi`] is the contract (hooks, kernel API, return convention, limits), [`layout`] how a
//! module sits in a flash bank, [`validate`] the checks with their errors, [`runtime`] the
//! engine and the program, [`host`] flashing and listing over the existing client. A board
//! runs modules once its registry has the runtime (`Board::with_registry`, or
//! `board.registry_mut().set_module_runtime(Box::new(WasmRuntime::new()))`).
#![forbid(unsafe_code)]

pub mod abi;
pub mod host;
pub mod layout;
pub mod runtime;
pub mod validate;

pub use runtime::{WasmProgram, WasmRuntime};
pub use validate::{ModuleError, ModuleInfo};
