//! Checks a module against the contract ([`crate::abi`]) before it is written or run: every
//! import a kernel service with its signature, every exported function a hook with its
//! signature, memory within the limit. The errors name what is wrong and what is allowed.

use wasmi::{Engine, ExternType, FuncType, Module, ValType};

use crate::abi::{self, Hook, IMPORT_MODULE, MAX_MEMORY_PAGES, Ty};
use crate::layout::{LayoutError, MAX_MODULE};

/// Why a module is refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ModuleError {
    #[error("the module is {0} bytes; at most {MAX_MODULE} fit in a flash bank")]
    TooLarge(usize),
    #[error("not a valid WebAssembly module: {0}")]
    Invalid(String),
    #[error(
        "imports `{module}.{name}`: the kernel API is the import module `kernel` (docs/cpu196.md)"
    )]
    ForeignImport { module: String, name: String },
    #[error("imports `kernel.{name}`, which is no kernel service (known: {known})")]
    UnknownImport { name: String, known: String },
    #[error("imports `kernel.{name}` as {found}; it is {expected}")]
    ImportType {
        name: &'static str,
        expected: String,
        found: String,
    },
    #[error("exports the function `{name}`, which is no hook (hooks: {known})")]
    UnknownExport { name: String, known: String },
    #[error("exports the hook `{name}` as {found}; it is {expected}")]
    HookType {
        name: &'static str,
        expected: String,
        found: String,
    },
    #[error("exports no hook (hooks: {0})")]
    NoHooks(String),
    #[error(
        "exports its memory as `{0}`; the kernel reads and writes it only under the name `memory`"
    )]
    MemoryName(String),
    #[error(
        "imports `kernel.{0}`, which reads or writes the module's memory, but exports no `memory`"
    )]
    NoMemory(&'static str),
    #[error("asks for {0} pages of memory at start; at most {MAX_MEMORY_PAGES} (64 KiB each)")]
    TooMuchMemory(u64),
    #[error("cannot be instantiated: {0}")]
    Instantiate(String),
    #[error(transparent)]
    Layout(#[from] LayoutError),
}

/// What a valid module has.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ModuleInfo {
    /// Hooks exported, in the order of [`Hook::ALL`].
    pub hooks: Vec<Hook>,
    /// Kernel services imported, in the module's order.
    pub imports: Vec<&'static str>,
    /// Memory pages at start (none: no memory).
    pub memory_pages: Option<u64>,
}

fn tys(types: &[ValType]) -> Option<Vec<Ty>> {
    types
        .iter()
        .map(|t| match t {
            ValType::I32 => Some(Ty::I32),
            ValType::I64 => Some(Ty::I64),
            _ => None,
        })
        .collect()
}

fn matches(ty: &FuncType, sig: &abi::Signature) -> bool {
    tys(ty.params()).as_deref() == Some(sig.params)
        && tys(ty.results()).as_deref() == Some(sig.results)
}

fn describe(ty: &FuncType) -> String {
    let show = |t: &[ValType]| {
        t.iter()
            .map(|v| format!("{v:?}").to_lowercase())
            .collect::<Vec<_>>()
            .join(", ")
    };
    match ty.results() {
        [] => format!("({})", show(ty.params())),
        r => format!("({}) -> {}", show(ty.params()), show(r)),
    }
}

fn describe_extern(ty: &ExternType) -> String {
    match ty {
        ExternType::Func(f) => describe(f),
        ExternType::Memory(_) => "a memory".into(),
        ExternType::Table(_) => "a table".into(),
        ExternType::Global(_) => "a global".into(),
    }
}

fn hook_names() -> String {
    Hook::ALL.map(Hook::name).join(", ")
}

/// Parses and checks `bytes`; the compiled module and what it has.
pub fn check(engine: &Engine, bytes: &[u8]) -> Result<(Module, ModuleInfo), ModuleError> {
    if bytes.len() > MAX_MODULE {
        return Err(ModuleError::TooLarge(bytes.len()));
    }
    // Validated whole first: wasmi 2.0.0 translates each operator as it validates it, and an
    // operator after a function's final `end` trips a debug assertion in its fuel metering
    // before the validator refuses the body (a panic in debug builds).
    wasmparser::Validator::new()
        .validate_all(bytes)
        .map_err(|e| ModuleError::Invalid(e.to_string()))?;
    let module = Module::new(engine, bytes).map_err(|e| ModuleError::Invalid(e.to_string()))?;
    let mut imports = Vec::new();
    for import in module.imports() {
        if import.module() != IMPORT_MODULE {
            return Err(ModuleError::ForeignImport {
                module: import.module().into(),
                name: import.name().into(),
            });
        }
        let Some(sig) = abi::import(import.name()) else {
            return Err(ModuleError::UnknownImport {
                name: import.name().into(),
                known: abi::IMPORTS.map(|s| s.name).join(", "),
            });
        };
        match import.ty() {
            ExternType::Func(f) if matches(f, sig) => imports.push(sig.name),
            other => {
                return Err(ModuleError::ImportType {
                    name: sig.name,
                    expected: sig.describe(),
                    found: describe_extern(other),
                });
            }
        }
    }
    let mut hooks = Vec::new();
    let mut memory_pages = None;
    for export in module.exports() {
        match export.ty() {
            ExternType::Func(f) => {
                let Some(hook) = Hook::by_name(export.name()) else {
                    return Err(ModuleError::UnknownExport {
                        name: export.name().into(),
                        known: hook_names(),
                    });
                };
                if !matches(f, hook.signature()) {
                    return Err(ModuleError::HookType {
                        name: hook.name(),
                        expected: hook.signature().describe(),
                        found: describe(f),
                    });
                }
                hooks.push(hook);
            }
            ExternType::Memory(m) if export.name() == "memory" => {
                if m.minimum() > MAX_MEMORY_PAGES {
                    return Err(ModuleError::TooMuchMemory(m.minimum()));
                }
                memory_pages = Some(m.minimum());
            }
            ExternType::Memory(_) => return Err(ModuleError::MemoryName(export.name().into())),
            // Globals and tables (a linker's `__heap_base`, say) are the module's business.
            ExternType::Global(_) | ExternType::Table(_) => {}
        }
    }
    if hooks.is_empty() {
        return Err(ModuleError::NoHooks(hook_names()));
    }
    if memory_pages.is_none()
        && let Some(name) = imports.iter().find(|n| abi::USES_MEMORY.contains(n))
    {
        return Err(ModuleError::NoMemory(name));
    }
    hooks.sort_by_key(|h| *h as usize);
    Ok((
        module,
        ModuleInfo {
            hooks,
            imports,
            memory_pages,
        },
    ))
}
