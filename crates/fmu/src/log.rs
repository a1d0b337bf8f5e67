//! The importer's logger, as each FMI version hands it over: FMI 2's variadic
//! `fmi2CallbackLogger` (called with the message as `"%s"`'s argument, so that a `%` in a path
//! or a name is never read as a format), FMI 3's `fmi3LogMessageCallback`.
#![allow(unsafe_code)]

use std::ffi::{c_char, c_int, c_void, CString};

/// A message's status (the values of both versions' status enumerations).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Status {
    Warning = 1,
    Error = 3,
}

impl Status {
    fn category(self) -> &'static str {
        match self {
            Status::Warning => "logStatusWarning",
            Status::Error => "logStatusError",
        }
    }
}

/// `fmi2CallbackLogger`: `(environment, instance name, status, category, message, ...)`.
pub(crate) type Fmi2Logger =
    unsafe extern "C" fn(*mut c_void, *const c_char, c_int, *const c_char, *const c_char, ...);

/// `fmi3LogMessageCallback`: `(environment, status, category, message)`.
pub(crate) type Fmi3Logger = unsafe extern "C" fn(*mut c_void, c_int, *const c_char, *const c_char);

/// Where an instance's messages go.
#[derive(Clone)]
pub(crate) enum Logger {
    /// Nowhere (the importer gave no logger).
    None,
    /// An FMI 2 importer's logger with its environment and the instance's name.
    Fmi2 {
        f: Fmi2Logger,
        env: *mut c_void,
        name: CString,
    },
    /// An FMI 3 importer's logger with its environment.
    Fmi3 { f: Fmi3Logger, env: *mut c_void },
}

/// `s` as a C string (an inner NUL, which no message of ours has, cut there).
fn c_string(s: &str) -> CString {
    let end = s.find('\0').unwrap_or(s.len());
    CString::new(&s[..end]).unwrap_or_default()
}

impl Logger {
    /// Hand `message` to the importer under `status`'s category.
    pub(crate) fn log(&self, status: Status, message: &str) {
        let category = c_string(status.category());
        let text = c_string(message);
        match self {
            Logger::None => {}
            Logger::Fmi2 { f, env, name } => {
                // SAFETY: the importer's logger, called as FMI 2 defines it; every pointer is to
                // a NUL-terminated string alive over the call.
                unsafe {
                    f(
                        *env,
                        name.as_ptr(),
                        status as c_int,
                        category.as_ptr(),
                        c"%s".as_ptr(),
                        text.as_ptr(),
                    )
                }
            }
            Logger::Fmi3 { f, env } => {
                // SAFETY: the importer's logger, called as FMI 3 defines it.
                unsafe { f(*env, status as c_int, category.as_ptr(), text.as_ptr()) }
            }
        }
    }
}
