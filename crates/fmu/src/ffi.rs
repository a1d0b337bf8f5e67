//! What both FMI versions' C functions share: their status codes (the same numbers in FMI 2
//! and 3), a call on an instance with its refusal logged and a panic caught (never unwound
//! into the importer), the importer's arrays read safely, the resources' location.
#![allow(unsafe_code)]

use crate::instance::{Instance, Refusal};
use crate::variables::Type;
use std::ffi::{c_char, c_int, c_void, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;

/// `fmi2OK`, `fmi3OK`.
pub(crate) const OK: c_int = 0;
/// `fmi2Error`, `fmi3Error`.
pub(crate) const ERROR: c_int = 3;

/// A panic's message.
fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic".into())
}

/// Run `f` on the instance behind `c`: OK, or ERROR with the refusal logged as
/// "`what`: reason". A panic is caught, logged, and leaves the instance failed.
///
/// # Safety
/// `c` is null or an instance this library made and has not freed.
pub(crate) unsafe fn call(
    c: *mut c_void,
    what: &str,
    f: impl FnOnce(&mut Instance) -> Result<(), Refusal>,
) -> c_int {
    let inst = c.cast::<Instance>();
    // SAFETY: the caller's promise.
    let Some(first) = (unsafe { inst.as_mut() }) else {
        return ERROR;
    };
    let outcome = catch_unwind(AssertUnwindSafe(|| f(first)));
    // SAFETY: as above; the closure's borrow has ended.
    let Some(inst) = (unsafe { inst.as_mut() }) else {
        return ERROR;
    };
    match outcome {
        Ok(Ok(())) => OK,
        Ok(Err(m)) => {
            inst.refuse(format!("{what}: {m}"));
            ERROR
        }
        Err(p) => {
            inst.fail();
            inst.refuse(format!(
                "{what}: internal error ({}); the instance cannot go on (a bug in physid: please report it)",
                panic_text(p.as_ref())
            ));
            ERROR
        }
    }
}

/// Read `nvr` variables of type `ty` into the importer's `n` values through `put` (every
/// variable here is a scalar: the counts must agree).
///
/// # Safety
/// As for [`call`], and the arrays as the FMI getters define them.
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn get_values<T>(
    c: *mut c_void,
    what: &str,
    ty: Type,
    vr: *const u32,
    nvr: usize,
    out: *mut T,
    n: usize,
    put: impl Fn(f64) -> T,
) -> c_int {
    // SAFETY: the caller's promise.
    unsafe {
        call(c, what, |i| {
            scalars(nvr, n)?;
            let vr = slice(vr, nvr, "value references")?;
            for (o, &r) in slice_mut(out, n, "values")?.iter_mut().zip(vr) {
                *o = put(i.get(r, ty)?);
            }
            Ok(())
        })
    }
}

/// Write `nvr` variables of type `ty` from the importer's `n` values through `take`.
///
/// # Safety
/// As for [`call`], and the arrays as the FMI setters define them.
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn set_values<T: Copy>(
    c: *mut c_void,
    what: &str,
    ty: Type,
    vr: *const u32,
    nvr: usize,
    values: *const T,
    n: usize,
    take: impl Fn(T) -> f64,
) -> c_int {
    // SAFETY: the caller's promise.
    unsafe {
        call(c, what, |i| {
            scalars(nvr, n)?;
            let vr = slice(vr, nvr, "value references")?;
            for (&v, &r) in slice(values, n, "values")?.iter().zip(vr) {
                i.set(r, ty, take(v))?;
            }
            Ok(())
        })
    }
}

/// The importer's counts agree (every variable here is a scalar).
fn scalars(nvr: usize, n: usize) -> Result<(), String> {
    if nvr == n {
        Ok(())
    } else {
        Err(format!(
            "{nvr} value references but {n} values (every variable here is a scalar)"
        ))
    }
}

/// C functions refused with a reason, for what an FMU does not do: `name(arguments after
/// the instance) => reason`, each returning the error status with the reason logged.
macro_rules! refused {
    ($( $name:ident ( $( $arg:ident : $ty:ty ),* ) => $why:expr ; )*) => { $(
        /// Refused with the error status and the reason through the logger.
        ///
        /// # Safety
        /// The FMI standard's contract for this function.
        #[no_mangle]
        pub unsafe extern "C" fn $name(instance: *mut std::ffi::c_void $(, $arg: $ty )*) -> std::ffi::c_int {
            $( let _ = $arg; )*
            // SAFETY: the FMI standard's contract.
            unsafe { $crate::ffi::call(instance, stringify!($name), |_| Err($why.to_string())) }
        }
    )* };
}
pub(crate) use refused;

/// A panic-free call that makes something (an instance): `None` on a panic.
pub(crate) fn guard<T>(f: impl FnOnce() -> Option<T>) -> Option<T> {
    catch_unwind(AssertUnwindSafe(f)).ok().flatten()
}

/// The importer's array of `n` items at `p` (empty when `n` is 0).
///
/// # Safety
/// `p` points to `n` items alive over the call, or is null.
pub(crate) unsafe fn slice<'a, T>(p: *const T, n: usize, what: &str) -> Result<&'a [T], Refusal> {
    if n == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err(format!("{what}: a null array of {n} items"));
    }
    // SAFETY: the caller's promise.
    Ok(unsafe { std::slice::from_raw_parts(p, n) })
}

/// The importer's writable array of `n` items at `p`.
///
/// # Safety
/// `p` points to `n` writable items alive over the call, or is null.
pub(crate) unsafe fn slice_mut<'a, T>(
    p: *mut T,
    n: usize,
    what: &str,
) -> Result<&'a mut [T], Refusal> {
    if n == 0 {
        return Ok(&mut []);
    }
    if p.is_null() {
        return Err(format!("{what}: a null array of {n} items"));
    }
    // SAFETY: the caller's promise.
    Ok(unsafe { std::slice::from_raw_parts_mut(p, n) })
}

/// The instance behind `c` as it is, into `*state`: a new saved state, or the one already
/// there overwritten.
///
/// # Safety
/// `c` as for [`call`]; `state` is null or points to null or to a state [`save`] made.
pub(crate) unsafe fn save(c: *mut c_void, what: &str, state: *mut *mut c_void) -> c_int {
    // SAFETY: the caller's promise.
    unsafe {
        call(c, what, |i| {
            let slot = state.as_mut().ok_or("a null pointer for the state")?;
            match slot.cast::<Instance>().as_mut() {
                Some(saved) => *saved = i.clone(),
                None => *slot = Box::into_raw(Box::new(i.clone())).cast::<c_void>(),
            }
            Ok(())
        })
    }
}

/// The instance behind `c` back to a saved state.
///
/// # Safety
/// `c` as for [`call`]; `state` is null or a state [`save`] made.
pub(crate) unsafe fn restore(c: *mut c_void, what: &str, state: *mut c_void) -> c_int {
    // SAFETY: the caller's promise.
    unsafe {
        call(c, what, |i| {
            let saved = state.cast::<Instance>().as_ref().ok_or("a null state")?;
            i.restore(saved);
            Ok(())
        })
    }
}

/// Free a saved state and null the importer's pointer to it.
///
/// # Safety
/// `c` as for [`call`]; `state` is null or points to null or to a state [`save`] made, not
/// used again.
pub(crate) unsafe fn free_state(c: *mut c_void, what: &str, state: *mut *mut c_void) -> c_int {
    // SAFETY: the caller's promise.
    unsafe {
        call(c, what, |_| {
            if let Some(slot) = state.as_mut() {
                if !slot.is_null() {
                    drop(Box::from_raw(slot.cast::<Instance>()));
                    *slot = std::ptr::null_mut();
                }
            }
            Ok(())
        })
    }
}

/// A C string's text (`None` when null or not UTF-8).
///
/// # Safety
/// `s` is null or a NUL-terminated string alive over the call.
pub(crate) unsafe fn text<'a>(s: *const c_char) -> Option<&'a str> {
    if s.is_null() {
        return None;
    }
    // SAFETY: the caller's promise.
    unsafe { CStr::from_ptr(s) }.to_str().ok()
}

/// The directory of a `file:` URI (FMI 2's `fmuResourceLocation`), percent-decoded:
/// `file:///a/b`, `file://localhost/a/b` and `file:/a/b` all give `/a/b`.
pub(crate) fn uri_path(uri: &str) -> Result<PathBuf, String> {
    let rest = uri
        .strip_prefix("file://localhost")
        .or_else(|| uri.strip_prefix("file://"))
        .or_else(|| uri.strip_prefix("file:"))
        .ok_or_else(|| format!("resource location '{uri}': expected a file: URI"))?;
    let bytes = rest.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        match (
            bytes[i],
            bytes.get(i + 1).copied(),
            bytes.get(i + 2).copied(),
        ) {
            (b'%', Some(h), Some(l)) if hex(h).is_some() && hex(l).is_some() => {
                out.push((hex(h).unwrap_or(0) * 16 + hex(l).unwrap_or(0)) as u8);
                i += 3;
            }
            (b, _, _) => {
                out.push(b);
                i += 1;
            }
        }
    }
    let path = String::from_utf8(out)
        .map_err(|_| format!("resource location '{uri}': not UTF-8 once decoded"))?;
    Ok(PathBuf::from(path))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn file_uris_decode() {
        for (uri, path) in [
            ("file:///tmp/a%20b/resources", "/tmp/a b/resources"),
            ("file://localhost/tmp/x/", "/tmp/x/"),
            ("file:/tmp/x%25y", "/tmp/x%y"),
        ] {
            assert_eq!(uri_path(uri).unwrap(), PathBuf::from(path));
        }
        assert!(uri_path("http://example.invalid/x").is_err());
    }
}
