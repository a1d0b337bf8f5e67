//! The FMI 3.0 co-simulation functions (the standard's `fmi3Functions.h`), each over one
//! [`Instance`]. The variables are `Float64` and `Boolean` scalars; the other types, model
//! exchange, scheduled execution, clocks, event mode, serialised states and derivatives are
//! refused with `fmi3Error` and a message through the importer's logger (the description
//! declares none of them).
#![allow(unsafe_code, non_snake_case, missing_docs)]

use crate::ffi::{call, get_values, guard, refused, set_values, text};
use crate::instance::Instance;
use crate::log::{Fmi3Logger, Logger, Status};
use crate::variables::Type;
use std::ffi::{c_char, c_int, c_void};
use std::path::PathBuf;

type Inst = *mut c_void;
type Status3 = c_int;
type Vr = u32;

#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    c"3.0".as_ptr()
}

/// # Safety
/// FMI 3's contract for `fmi3InstantiateCoSimulation`.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    _instance_name: *const c_char,
    token: *const c_char,
    resource_path: *const c_char,
    _visible: bool,
    logging_on: bool,
    event_mode_used: bool,
    _early_return_allowed: bool,
    _required_intermediate: *const Vr,
    _n_required_intermediate: usize,
    environment: *mut c_void,
    log_message: Option<Fmi3Logger>,
    _intermediate_update: *const c_void,
) -> Inst {
    guard(|| {
        let logger = match log_message {
            Some(f) => Logger::Fmi3 {
                f,
                env: environment,
            },
            None => Logger::None,
        };
        // SAFETY: FMI 3's contract: null or alive over the call.
        let (token, path) = unsafe { (text(token), text(resource_path)) };
        let made = (|| {
            if event_mode_used {
                return Err("this FMU has no event mode (hasEventMode=\"false\")".to_string());
            }
            let dir = PathBuf::from(path.ok_or("no resource path given")?);
            Instance::from_resources(&dir, token, logger.clone(), logging_on)
        })();
        match made {
            Ok(inst) => Some(Box::into_raw(Box::new(inst)).cast::<c_void>()),
            Err(e) => {
                logger.log(Status::Error, &format!("fmi3InstantiateCoSimulation: {e}"));
                None
            }
        }
    })
    .unwrap_or(std::ptr::null_mut())
}

/// Refused: this FMU is for co-simulation.
///
/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    _name: *const c_char,
    _token: *const c_char,
    _resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    environment: *mut c_void,
    log_message: Option<Fmi3Logger>,
) -> Inst {
    if let Some(f) = log_message {
        Logger::Fmi3 {
            f,
            env: environment,
        }
        .log(
            Status::Error,
            "fmi3InstantiateModelExchange: this FMU is for co-simulation only",
        );
    }
    std::ptr::null_mut()
}

/// Refused: this FMU is for co-simulation.
///
/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    _name: *const c_char,
    _token: *const c_char,
    _resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    environment: *mut c_void,
    log_message: Option<Fmi3Logger>,
    _clock_update: *const c_void,
    _lock_preemption: *const c_void,
    _unlock_preemption: *const c_void,
) -> Inst {
    if let Some(f) = log_message {
        Logger::Fmi3 {
            f,
            env: environment,
        }
        .log(
            Status::Error,
            "fmi3InstantiateScheduledExecution: this FMU is for co-simulation only",
        );
    }
    std::ptr::null_mut()
}

/// # Safety
/// `instance` is null or from `fmi3InstantiateCoSimulation`, not used again.
#[no_mangle]
pub unsafe extern "C" fn fmi3FreeInstance(instance: Inst) {
    if !instance.is_null() {
        // SAFETY: the caller's promise: ours, freed once.
        drop(unsafe { Box::from_raw(instance.cast::<Instance>()) });
    }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    instance: Inst,
    on: bool,
    _n: usize,
    _categories: *const *const c_char,
) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe {
        call(instance, "fmi3SetDebugLogging", |i| {
            i.logging = on;
            Ok(())
        })
    }
}

/// The experiment (start, stop) and initialisation mode in one, as FMI 3 has it.
///
/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    instance: Inst,
    _tolerance_defined: bool,
    _tolerance: f64,
    start: f64,
    stop_defined: bool,
    stop: f64,
) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe {
        call(instance, "fmi3EnterInitializationMode", |i| {
            i.setup(start, stop_defined.then_some(stop))?;
            i.enter_initialization()
        })
    }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3ExitInitializationMode(instance: Inst) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe {
        call(
            instance,
            "fmi3ExitInitializationMode",
            Instance::exit_initialization,
        )
    }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3Terminate(instance: Inst) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe { call(instance, "fmi3Terminate", Instance::terminate) }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3Reset(instance: Inst) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe {
        call(instance, "fmi3Reset", |i| {
            i.reset();
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3DoStep(
    instance: Inst,
    t: f64,
    h: f64,
    _no_set_prior: bool,
    event_handling_needed: *mut bool,
    terminate_simulation: *mut bool,
    early_return: *mut bool,
    last_successful_time: *mut f64,
) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe {
        call(instance, "fmi3DoStep", |i| {
            let done = i.do_step(t, h);
            for flag in [event_handling_needed, terminate_simulation, early_return] {
                if let Some(f) = flag.as_mut() {
                    *f = false;
                }
            }
            if let Some(last) = last_successful_time.as_mut() {
                *last = i.time();
            }
            done
        })
    }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetFloat64(
    instance: Inst,
    vr: *const Vr,
    nvr: usize,
    values: *mut f64,
    n: usize,
) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe {
        get_values(
            instance,
            "fmi3GetFloat64",
            Type::Real,
            vr,
            nvr,
            values,
            n,
            |x| x,
        )
    }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetFloat64(
    instance: Inst,
    vr: *const Vr,
    nvr: usize,
    values: *const f64,
    n: usize,
) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe {
        set_values(
            instance,
            "fmi3SetFloat64",
            Type::Real,
            vr,
            nvr,
            values,
            n,
            |x| x,
        )
    }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetBoolean(
    instance: Inst,
    vr: *const Vr,
    nvr: usize,
    values: *mut bool,
    n: usize,
) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe {
        get_values(
            instance,
            "fmi3GetBoolean",
            Type::Boolean,
            vr,
            nvr,
            values,
            n,
            |x| x != 0.0,
        )
    }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetBoolean(
    instance: Inst,
    vr: *const Vr,
    nvr: usize,
    values: *const bool,
    n: usize,
) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe {
        set_values(
            instance,
            "fmi3SetBoolean",
            Type::Boolean,
            vr,
            nvr,
            values,
            n,
            |x| f64::from(u8::from(x)),
        )
    }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetFMUState(instance: Inst, state: *mut *mut c_void) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe { crate::ffi::save(instance, "fmi3GetFMUState", state) }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetFMUState(instance: Inst, state: *mut c_void) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe { crate::ffi::restore(instance, "fmi3SetFMUState", state) }
}

/// # Safety
/// FMI 3's contract.
#[no_mangle]
pub unsafe extern "C" fn fmi3FreeFMUState(instance: Inst, state: *mut *mut c_void) -> Status3 {
    // SAFETY: FMI 3's contract.
    unsafe { crate::ffi::free_state(instance, "fmi3FreeFMUState", state) }
}

const NO_TYPE: &str =
    "this FMU has no variable of that type (its variables are Float64 and Boolean)";
const NO_EVENTS: &str = "this FMU has no event mode, clocks or configuration mode";
const CO_SIMULATION: &str = "this FMU is for co-simulation only";
const NO_SERIALIZE: &str = "this FMU does not serialise its state (canSerializeFMUState=\"false\"); fmi3GetFMUState and fmi3SetFMUState roll back within the process";
const NO_DERIVATIVES: &str = "this FMU gives no derivatives (providesDirectionalDerivatives and providesAdjointDerivatives are false)";

refused! {
    fmi3GetFloat32(vr: *const Vr, nvr: usize, v: *mut f32, n: usize) => NO_TYPE;
    fmi3SetFloat32(vr: *const Vr, nvr: usize, v: *const f32, n: usize) => NO_TYPE;
    fmi3GetInt8(vr: *const Vr, nvr: usize, v: *mut i8, n: usize) => NO_TYPE;
    fmi3SetInt8(vr: *const Vr, nvr: usize, v: *const i8, n: usize) => NO_TYPE;
    fmi3GetUInt8(vr: *const Vr, nvr: usize, v: *mut u8, n: usize) => NO_TYPE;
    fmi3SetUInt8(vr: *const Vr, nvr: usize, v: *const u8, n: usize) => NO_TYPE;
    fmi3GetInt16(vr: *const Vr, nvr: usize, v: *mut i16, n: usize) => NO_TYPE;
    fmi3SetInt16(vr: *const Vr, nvr: usize, v: *const i16, n: usize) => NO_TYPE;
    fmi3GetUInt16(vr: *const Vr, nvr: usize, v: *mut u16, n: usize) => NO_TYPE;
    fmi3SetUInt16(vr: *const Vr, nvr: usize, v: *const u16, n: usize) => NO_TYPE;
    fmi3GetInt32(vr: *const Vr, nvr: usize, v: *mut i32, n: usize) => NO_TYPE;
    fmi3SetInt32(vr: *const Vr, nvr: usize, v: *const i32, n: usize) => NO_TYPE;
    fmi3GetUInt32(vr: *const Vr, nvr: usize, v: *mut u32, n: usize) => NO_TYPE;
    fmi3SetUInt32(vr: *const Vr, nvr: usize, v: *const u32, n: usize) => NO_TYPE;
    fmi3GetInt64(vr: *const Vr, nvr: usize, v: *mut i64, n: usize) => NO_TYPE;
    fmi3SetInt64(vr: *const Vr, nvr: usize, v: *const i64, n: usize) => NO_TYPE;
    fmi3GetUInt64(vr: *const Vr, nvr: usize, v: *mut u64, n: usize) => NO_TYPE;
    fmi3SetUInt64(vr: *const Vr, nvr: usize, v: *const u64, n: usize) => NO_TYPE;
    fmi3GetString(vr: *const Vr, nvr: usize, v: *mut *const c_char, n: usize) => NO_TYPE;
    fmi3SetString(vr: *const Vr, nvr: usize, v: *const *const c_char, n: usize) => NO_TYPE;
    fmi3GetBinary(vr: *const Vr, nvr: usize, sizes: *mut usize, v: *mut *const u8, n: usize) => NO_TYPE;
    fmi3SetBinary(vr: *const Vr, nvr: usize, sizes: *const usize, v: *const *const u8, n: usize) => NO_TYPE;
    fmi3GetClock(vr: *const Vr, nvr: usize, v: *mut bool) => NO_EVENTS;
    fmi3SetClock(vr: *const Vr, nvr: usize, v: *const bool) => NO_EVENTS;
    fmi3GetNumberOfVariableDependencies(vr: Vr, n: *mut usize) => "this FMU gives no dependency information (every output depends on every input)";
    fmi3GetVariableDependencies(dependent: Vr, element_dependent: *mut usize, independents: *mut Vr, element_independents: *mut usize, kinds: *mut c_int, n: usize) => "this FMU gives no dependency information (every output depends on every input)";
    fmi3SerializedFMUStateSize(state: *mut c_void, size: *mut usize) => NO_SERIALIZE;
    fmi3SerializeFMUState(state: *mut c_void, bytes: *mut u8, size: usize) => NO_SERIALIZE;
    fmi3DeserializeFMUState(bytes: *const u8, size: usize, state: *mut *mut c_void) => NO_SERIALIZE;
    fmi3GetDirectionalDerivative(unknowns: *const Vr, n_unknowns: usize, knowns: *const Vr, n_knowns: usize, seed: *const f64, n_seed: usize, sensitivity: *mut f64, n_sensitivity: usize) => NO_DERIVATIVES;
    fmi3GetAdjointDerivative(unknowns: *const Vr, n_unknowns: usize, knowns: *const Vr, n_knowns: usize, seed: *const f64, n_seed: usize, sensitivity: *mut f64, n_sensitivity: usize) => NO_DERIVATIVES;
    fmi3EnterConfigurationMode() => NO_EVENTS;
    fmi3ExitConfigurationMode() => NO_EVENTS;
    fmi3GetIntervalDecimal(vr: *const Vr, nvr: usize, intervals: *mut f64, qualifiers: *mut c_int) => NO_EVENTS;
    fmi3GetIntervalFraction(vr: *const Vr, nvr: usize, counters: *mut u64, resolutions: *mut u64, qualifiers: *mut c_int) => NO_EVENTS;
    fmi3GetShiftDecimal(vr: *const Vr, nvr: usize, shifts: *mut f64) => NO_EVENTS;
    fmi3GetShiftFraction(vr: *const Vr, nvr: usize, counters: *mut u64, resolutions: *mut u64) => NO_EVENTS;
    fmi3SetIntervalDecimal(vr: *const Vr, nvr: usize, intervals: *const f64) => NO_EVENTS;
    fmi3SetIntervalFraction(vr: *const Vr, nvr: usize, counters: *const u64, resolutions: *const u64) => NO_EVENTS;
    fmi3SetShiftDecimal(vr: *const Vr, nvr: usize, shifts: *const f64) => NO_EVENTS;
    fmi3SetShiftFraction(vr: *const Vr, nvr: usize, counters: *const u64, resolutions: *const u64) => NO_EVENTS;
    fmi3EvaluateDiscreteStates() => NO_EVENTS;
    fmi3UpdateDiscreteStates(update_needed: *mut bool, terminate: *mut bool, nominals_changed: *mut bool, values_changed: *mut bool, next_defined: *mut bool, next_time: *mut f64) => NO_EVENTS;
    fmi3EnterEventMode() => NO_EVENTS;
    fmi3EnterStepMode() => "the instance is in step mode from fmi3ExitInitializationMode on (this FMU has no event mode)";
    fmi3EnterContinuousTimeMode() => CO_SIMULATION;
    fmi3CompletedIntegratorStep(no_set_prior: bool, enter_event_mode: *mut bool, terminate: *mut bool) => CO_SIMULATION;
    fmi3SetTime(time: f64) => CO_SIMULATION;
    fmi3SetContinuousStates(x: *const f64, n: usize) => CO_SIMULATION;
    fmi3GetContinuousStateDerivatives(dx: *mut f64, n: usize) => CO_SIMULATION;
    fmi3GetEventIndicators(z: *mut f64, n: usize) => CO_SIMULATION;
    fmi3GetContinuousStates(x: *mut f64, n: usize) => CO_SIMULATION;
    fmi3GetNominalsOfContinuousStates(x: *mut f64, n: usize) => CO_SIMULATION;
    fmi3GetNumberOfEventIndicators(n: *mut usize) => CO_SIMULATION;
    fmi3GetNumberOfContinuousStates(n: *mut usize) => CO_SIMULATION;
    fmi3GetOutputDerivatives(vr: *const Vr, nvr: usize, orders: *const i32, v: *mut f64, n: usize) => "this FMU gives no output derivatives (maxOutputDerivativeOrder is 0)";
    fmi3ActivateModelPartition(clock: Vr, time: f64) => NO_EVENTS;
}
