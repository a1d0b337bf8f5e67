//! The FMI 2.0 co-simulation functions (the standard's `fmi2Functions.h`), each over one
//! [`Instance`]. What a function cannot do here (serialise a state, interpolate inputs,
//! directional derivatives, asynchronous steps: the description says so) it refuses with
//! `fmi2Error` and a message through the importer's logger.
#![allow(unsafe_code, non_snake_case, missing_docs)]

use crate::ffi::{call, get_values, guard, refused, set_values, slice_mut, text, uri_path};
use crate::instance::Instance;
use crate::log::{Fmi2Logger, Logger, Status};
use crate::variables::Type;
use std::ffi::{c_char, c_int, c_void, CString};

type Component = *mut c_void;
type Status2 = c_int;
type Vr = u32;

/// `fmi2CallbackFunctions`.
#[repr(C)]
pub struct CallbackFunctions {
    logger: Option<Fmi2Logger>,
    allocate_memory: Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>,
    free_memory: Option<unsafe extern "C" fn(*mut c_void)>,
    step_finished: Option<unsafe extern "C" fn(*mut c_void, c_int)>,
    component_environment: *mut c_void,
}

/// `fmi2CoSimulation`.
const CO_SIMULATION: c_int = 1;

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// # Safety
/// FMI 2's contract for `fmi2Instantiate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: *const c_char,
    fmu_type: c_int,
    guid: *const c_char,
    resource_location: *const c_char,
    functions: *const CallbackFunctions,
    _visible: c_int,
    logging_on: c_int,
) -> Component {
    guard(|| {
        // SAFETY: FMI 2's contract: null or alive over the call.
        let (name, guid, location) =
            unsafe { (text(instance_name), text(guid), text(resource_location)) };
        let name = CString::new(name.unwrap_or("physid_cell")).unwrap_or_default();
        // SAFETY: as above.
        let logger = match unsafe { functions.as_ref() }.and_then(|f| f.logger.map(|l| (l, f))) {
            Some((f, cb)) => Logger::Fmi2 {
                f,
                env: cb.component_environment,
                name,
            },
            None => Logger::None,
        };
        let made = (|| {
            if fmu_type != CO_SIMULATION {
                return Err(format!(
                    "this FMU is for co-simulation (fmi2CoSimulation = 1), not type {fmu_type}"
                ));
            }
            let dir = uri_path(location.ok_or("no resource location given")?)?;
            Instance::from_resources(&dir, guid, logger.clone(), logging_on != 0)
        })();
        match made {
            Ok(inst) => Some(Box::into_raw(Box::new(inst)).cast::<c_void>()),
            Err(e) => {
                logger.log(Status::Error, &format!("fmi2Instantiate: {e}"));
                None
            }
        }
    })
    .unwrap_or(std::ptr::null_mut())
}

/// # Safety
/// `c` is null or an instance from `fmi2Instantiate`, not used again.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: Component) {
    if !c.is_null() {
        // SAFETY: the caller's promise: ours, freed once.
        drop(unsafe { Box::from_raw(c.cast::<Instance>()) });
    }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: Component,
    on: c_int,
    _n: usize,
    _categories: *const *const c_char,
) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe {
        call(c, "fmi2SetDebugLogging", |i| {
            i.logging = on != 0;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: Component,
    _tolerance_defined: c_int,
    _tolerance: f64,
    start: f64,
    stop_defined: c_int,
    stop: f64,
) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe {
        call(c, "fmi2SetupExperiment", |i| {
            i.setup(start, (stop_defined != 0).then_some(stop))
        })
    }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: Component) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe {
        call(
            c,
            "fmi2EnterInitializationMode",
            Instance::enter_initialization,
        )
    }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: Component) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe {
        call(
            c,
            "fmi2ExitInitializationMode",
            Instance::exit_initialization,
        )
    }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: Component) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe { call(c, "fmi2Terminate", Instance::terminate) }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: Component) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe {
        call(c, "fmi2Reset", |i| {
            i.reset();
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: Component,
    vr: *const Vr,
    n: usize,
    v: *mut f64,
) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe { get_values(c, "fmi2GetReal", Type::Real, vr, n, v, n, |x| x) }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: Component,
    vr: *const Vr,
    n: usize,
    v: *const f64,
) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe { set_values(c, "fmi2SetReal", Type::Real, vr, n, v, n, |x| x) }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: Component,
    vr: *const Vr,
    n: usize,
    v: *mut c_int,
) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe {
        get_values(c, "fmi2GetBoolean", Type::Boolean, vr, n, v, n, |x| {
            c_int::from(x != 0.0)
        })
    }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: Component,
    vr: *const Vr,
    n: usize,
    v: *const c_int,
) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe {
        set_values(c, "fmi2SetBoolean", Type::Boolean, vr, n, v, n, |x| {
            f64::from(u8::from(x != 0))
        })
    }
}

/// Refuse `n > 0` variables of a type the FMU has none of.
///
/// # Safety
/// FMI 2's contract.
unsafe fn none_of(c: Component, what: &str, n: usize) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe {
        call(c, what, |_| match n {
            0 => Ok(()),
            _ => Err(
                "this FMU has no variable of that type (its variables are Real and Boolean)".into(),
            ),
        })
    }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: Component,
    _vr: *const Vr,
    n: usize,
    _v: *mut c_int,
) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe { none_of(c, "fmi2GetInteger", n) }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: Component,
    _vr: *const Vr,
    n: usize,
    _v: *const c_int,
) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe { none_of(c, "fmi2SetInteger", n) }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: Component,
    _vr: *const Vr,
    n: usize,
    _v: *mut *const c_char,
) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe { none_of(c, "fmi2GetString", n) }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: Component,
    _vr: *const Vr,
    n: usize,
    _v: *const *const c_char,
) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe { none_of(c, "fmi2SetString", n) }
}

/// The instance as it is, into `*state` (a new one, or the one there overwritten).
///
/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: Component, state: *mut *mut c_void) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe { crate::ffi::save(c, "fmi2GetFMUstate", state) }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: Component, state: *mut c_void) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe { crate::ffi::restore(c, "fmi2SetFMUstate", state) }
}

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: Component, state: *mut *mut c_void) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe { crate::ffi::free_state(c, "fmi2FreeFMUstate", state) }
}

const NO_SERIALIZE: &str = "this FMU does not serialise its state (canSerializeFMUstate=\"false\"); fmi2GetFMUstate and fmi2SetFMUstate roll back within the process";

/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(c: Component, t: f64, h: f64, _no_set_prior: c_int) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe { call(c, "fmi2DoStep", |i| i.do_step(t, h)) }
}

const SYNCHRONOUS: &str = "every step here finishes within fmi2DoStep (no asynchronous steps)";

/// `fmi2LastSuccessfulTime`: the instance's time.
///
/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(c: Component, kind: c_int, v: *mut f64) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe {
        call(c, "fmi2GetRealStatus", |i| {
            let out = slice_mut(v, 1, "value")?;
            match kind {
                2 => {
                    out[0] = i.time();
                    Ok(())
                }
                _ => Err(SYNCHRONOUS.into()),
            }
        })
    }
}

/// `fmi2Terminated`: false (the cell never asks to stop).
///
/// # Safety
/// FMI 2's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(c: Component, kind: c_int, v: *mut c_int) -> Status2 {
    // SAFETY: FMI 2's contract.
    unsafe {
        call(c, "fmi2GetBooleanStatus", |_| {
            let out = slice_mut(v, 1, "value")?;
            match kind {
                3 => {
                    out[0] = 0;
                    Ok(())
                }
                _ => Err(SYNCHRONOUS.into()),
            }
        })
    }
}

refused! {
    fmi2SerializedFMUstateSize(state: *mut c_void, size: *mut usize) => NO_SERIALIZE;
    fmi2SerializeFMUstate(state: *mut c_void, bytes: *mut u8, size: usize) => NO_SERIALIZE;
    fmi2DeSerializeFMUstate(bytes: *const u8, size: usize, state: *mut *mut c_void) => NO_SERIALIZE;
    fmi2GetDirectionalDerivative(unknown: *const Vr, n_unknown: usize, known: *const Vr, n_known: usize, dv_known: *const f64, dv_unknown: *mut f64) => "this FMU gives no directional derivatives (providesDirectionalDerivative=\"false\")";
    fmi2SetRealInputDerivatives(vr: *const Vr, n: usize, order: *const c_int, v: *const f64) => "the inputs are held over a step (canInterpolateInputs=\"false\")";
    fmi2GetRealOutputDerivatives(vr: *const Vr, n: usize, order: *const c_int, v: *mut f64) => "this FMU gives no output derivatives (maxOutputDerivativeOrder=\"0\")";
    fmi2CancelStep() => SYNCHRONOUS;
    fmi2GetStatus(kind: c_int, v: *mut c_int) => SYNCHRONOUS;
    fmi2GetIntegerStatus(kind: c_int, v: *mut c_int) => SYNCHRONOUS;
    fmi2GetStringStatus(kind: c_int, v: *mut *const c_char) => SYNCHRONOUS;
}
