//! Panic boundaries around third-party decoders (EXR, PNG/JPEG, glTF): a panic on malformed
//! data becomes an error the caller can attach the file's name to, not a crash.

/// Runs `f`; a panic inside becomes `Err("malformed {what} (panic message)")`.
pub(crate) fn catch_panic<T>(what: &str, f: impl FnOnce() -> T) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|p| {
        let message = p.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| p.downcast_ref::<String>().cloned());
        format!("malformed {what} ({})", message.unwrap_or_else(|| "its reader gave up".into()))
    })
}
