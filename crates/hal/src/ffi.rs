//! # The one place with `unsafe` in truepos: the C interface of LinuxCNC's HAL library.
//!
//! LinuxCNC 2.9 (Debian `linuxcnc-uspace`) ships `liblinuxcnchal.so.0`; its header
//! `/usr/include/linuxcnc/hal.h` (package `linuxcnc-uspace-dev`) declares what a userspace
//! component calls: `hal_init`, `hal_malloc`, `hal_pin_{bit,s32,float}_new`, `hal_ready` and
//! `hal_exit`. The library is opened at run time (`dlopen` through `libloading`) rather than
//! linked, so that truepos builds and tests on machines without LinuxCNC; only running the
//! component needs it.
//!
//! The safe surface is [`Component`] and the typed pins [`FloatPin`], [`BitPin`] and
//! [`S32Pin`]. HAL's model, from `hal.h`: a pin is a pointer *slot* in HAL shared memory
//! (allocated with `hal_malloc`); `hal_pin_*_new` stores in the slot the address of the pin's
//! value, and `halcmd net` later re-points the slot at the signal's value. Reading a pin is
//! therefore two volatile loads (slot, then value), writing is a volatile load of the slot and a
//! volatile store. Every pin keeps the component alive (an [`Arc`]), so no slot is used after
//! `hal_exit` has freed the shared memory.

use std::ffi::{c_char, c_int, c_long, c_void, CString};
use std::fmt;
use std::sync::Arc;

/// Direction of a pin, as `hal_pin_dir_t` in `hal.h` (`HAL_IN = 16`, `HAL_OUT = 32`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// The component reads the pin.
    In,
    /// The component writes the pin.
    Out,
}

impl Direction {
    fn code(self) -> c_int {
        match self {
            Self::In => 16,
            Self::Out => 32,
        }
    }
}

/// What went wrong talking to HAL.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HalError {
    /// `liblinuxcnchal.so.0` or one of its functions could not be loaded.
    #[error("cannot load LinuxCNC's HAL library (install linuxcnc-uspace): {0}")]
    Library(String),
    /// A HAL call returned an error code (negative errno, see `rtapi_errno.h`).
    #[error("{function}(\"{name}\") failed with code {code}{hint}", hint = call_hint(.function))]
    Call {
        /// The C function.
        function: &'static str,
        /// Its argument (component or pin name).
        name: String,
        /// The code it returned.
        code: i32,
    },
    /// `hal_malloc` returned no memory.
    #[error("hal_malloc: HAL shared memory is exhausted")]
    OutOfMemory,
    /// A name contains a NUL byte or is longer than HAL's 47 characters (`HAL_NAME_LEN`).
    #[error("HAL name {0:?} must be at most 47 bytes long and contain no NUL")]
    BadName(String),
    /// A machine channel whose id would make a pin name `halcmd` cannot take.
    #[error("{0}")]
    NotAPinName(String),
}

/// What to try when a call failed: `hal_init` fails when the name is taken or HAL is not up.
fn call_hint(function: &str) -> &'static str {
    if function == "hal_init" {
        " (is LinuxCNC or halrun running, and is the name free?)"
    } else {
        ""
    }
}

/// `HAL_NAME_LEN` in `hal.h`.
const HAL_NAME_LEN: usize = 47;

type InitFn = unsafe extern "C" fn(*const c_char) -> c_int;
type ExitFn = unsafe extern "C" fn(c_int) -> c_int;
type MallocFn = unsafe extern "C" fn(c_long) -> *mut c_void;
type ReadyFn = unsafe extern "C" fn(c_int) -> c_int;
type PinNewFn<T> = unsafe extern "C" fn(*const c_char, c_int, *mut *mut T, c_int) -> c_int;

/// The loaded library and the functions truepos uses.
struct Library {
    // Kept so that the function pointers below stay valid.
    _lib: libloading::Library,
    init: InitFn,
    exit: ExitFn,
    malloc: MallocFn,
    ready: ReadyFn,
    pin_bit_new: PinNewFn<u8>,
    pin_s32_new: PinNewFn<i32>,
    pin_float_new: PinNewFn<f64>,
}

impl Library {
    fn open() -> Result<Self, HalError> {
        let err = |e: libloading::Error| HalError::Library(e.to_string());
        // SAFETY: loading liblinuxcnchal runs its ELF constructors; the library is LinuxCNC's
        // own, written to be loaded by userspace components (halcmd, the Python `hal` module).
        let lib = unsafe { libloading::Library::new("liblinuxcnchal.so.0") }.map_err(err)?;
        // SAFETY: each symbol is looked up with the exact C signature declared in LinuxCNC 2.9's
        // hal.h (`int hal_init(const char*)`, `int hal_exit(int)`, `void *hal_malloc(long)`,
        // `int hal_ready(int)`, `int hal_pin_X_new(const char*, hal_pin_dir_t, hal_X_t**, int)`
        // where hal_pin_dir_t is a C enum (int), hal_bit_t is `volatile bool`, hal_s32_t
        // `volatile int32_t` and hal_float_t `volatile double`). The copied function pointers
        // are only used while `_lib` (stored alongside) keeps the library mapped.
        unsafe {
            Ok(Self {
                init: *lib.get::<InitFn>(b"hal_init\0").map_err(err)?,
                exit: *lib.get::<ExitFn>(b"hal_exit\0").map_err(err)?,
                malloc: *lib.get::<MallocFn>(b"hal_malloc\0").map_err(err)?,
                ready: *lib.get::<ReadyFn>(b"hal_ready\0").map_err(err)?,
                pin_bit_new: *lib.get::<PinNewFn<u8>>(b"hal_pin_bit_new\0").map_err(err)?,
                pin_s32_new: *lib
                    .get::<PinNewFn<i32>>(b"hal_pin_s32_new\0")
                    .map_err(err)?,
                pin_float_new: *lib
                    .get::<PinNewFn<f64>>(b"hal_pin_float_new\0")
                    .map_err(err)?,
                _lib: lib,
            })
        }
    }
}

/// A registered HAL component; `hal_exit` runs when it and every pin made from it are dropped.
struct Inner {
    lib: Library,
    id: c_int,
    name: String,
}

impl Drop for Inner {
    fn drop(&mut self) {
        // SAFETY: `id` came from a successful `hal_init` and is exited exactly once, here, after
        // the last pin (each holds an `Arc<Inner>`) is gone, so no slot is used afterwards.
        unsafe {
            (self.lib.exit)(self.id);
        }
    }
}

/// A userspace HAL component (`halcmd show comp` lists it under its name).
#[derive(Clone)]
pub struct Component {
    inner: Arc<Inner>,
}

impl fmt::Debug for Component {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Component")
            .field("name", &self.inner.name)
            .field("id", &self.inner.id)
            .finish()
    }
}

fn c_name(name: &str) -> Result<CString, HalError> {
    if name.len() > HAL_NAME_LEN {
        return Err(HalError::BadName(name.to_string()));
    }
    CString::new(name).map_err(|_| HalError::BadName(name.to_string()))
}

impl Component {
    /// Loads the HAL library and registers a component called `name` (`hal_init`). HAL (a
    /// running LinuxCNC, or `halrun`) must be up.
    pub fn new(name: &str) -> Result<Self, HalError> {
        let lib = Library::open()?;
        let c = c_name(name)?;
        // SAFETY: `c` is a NUL-terminated string that outlives the call; hal_init copies it.
        let id = unsafe { (lib.init)(c.as_ptr()) };
        if id <= 0 {
            return Err(HalError::Call {
                function: "hal_init",
                name: name.to_string(),
                code: id,
            });
        }
        Ok(Self {
            inner: Arc::new(Inner {
                lib,
                id,
                name: name.to_string(),
            }),
        })
    }

    /// The component's name.
    pub fn name(&self) -> &str {
        &self.inner.name
    }

    /// Allocates one pin slot in HAL shared memory and registers `component.suffix` on it.
    fn pin_slot<T>(
        &self,
        suffix: &str,
        dir: Direction,
        new: PinNewFn<T>,
        function: &'static str,
    ) -> Result<*mut *mut T, HalError> {
        let full = format!("{}.{}", self.inner.name, suffix);
        let c = c_name(&full)?;
        let size = std::mem::size_of::<*mut T>() as c_long;
        // SAFETY: hal_malloc takes a size and returns memory in HAL shared memory (aligned for
        // any HAL type) or NULL; it is called from the thread that owns the component, before
        // hal_ready, as hal.h requires.
        let slot = unsafe { (self.inner.lib.malloc)(size) } as *mut *mut T;
        if slot.is_null() {
            return Err(HalError::OutOfMemory);
        }
        // SAFETY: `slot` is a fresh pointer-sized block in HAL shared memory, which is what
        // hal_pin_*_new requires for `data_ptr_addr`; `c` is NUL-terminated and outlives the
        // call; the component id is live (held by `self`).
        let code = unsafe { new(c.as_ptr(), dir.code(), slot, self.inner.id) };
        if code != 0 {
            return Err(HalError::Call {
                function,
                name: full,
                code,
            });
        }
        Ok(slot)
    }

    /// A float pin `component.suffix` (`hal_float_t`, a C double).
    pub fn float_pin(&self, suffix: &str, dir: Direction) -> Result<FloatPin, HalError> {
        let slot = self.pin_slot(
            suffix,
            dir,
            self.inner.lib.pin_float_new,
            "hal_pin_float_new",
        )?;
        Ok(FloatPin {
            slot,
            _owner: self.inner.clone(),
        })
    }

    /// A bit pin `component.suffix` (`hal_bit_t`, a C bool).
    pub fn bit_pin(&self, suffix: &str, dir: Direction) -> Result<BitPin, HalError> {
        let slot = self.pin_slot(suffix, dir, self.inner.lib.pin_bit_new, "hal_pin_bit_new")?;
        Ok(BitPin {
            slot,
            _owner: self.inner.clone(),
        })
    }

    /// A signed 32-bit pin `component.suffix` (`hal_s32_t`).
    pub fn s32_pin(&self, suffix: &str, dir: Direction) -> Result<S32Pin, HalError> {
        let slot = self.pin_slot(suffix, dir, self.inner.lib.pin_s32_new, "hal_pin_s32_new")?;
        Ok(S32Pin {
            slot,
            _owner: self.inner.clone(),
        })
    }

    /// Tells HAL that every pin exists (`hal_ready`); `loadusr -W` waits for this.
    pub fn ready(&self) -> Result<(), HalError> {
        // SAFETY: the id is live (held by `self`); hal_ready only flags the component.
        let code = unsafe { (self.inner.lib.ready)(self.inner.id) };
        if code != 0 {
            return Err(HalError::Call {
                function: "hal_ready",
                name: self.inner.name.clone(),
                code,
            });
        }
        Ok(())
    }
}

/// A float pin.
pub struct FloatPin {
    slot: *mut *mut f64,
    _owner: Arc<Inner>,
}

/// A bit pin.
pub struct BitPin {
    // hal_bit_t is a one-byte C bool; read as a byte so that a stray value is not UB in Rust.
    slot: *mut *mut u8,
    _owner: Arc<Inner>,
}

/// A signed 32-bit pin.
pub struct S32Pin {
    slot: *mut *mut i32,
    _owner: Arc<Inner>,
}

macro_rules! pin_access {
    ($pin:ty, $t:ty, $raw:ty, $from:expr, $to:expr) => {
        impl $pin {
            /// The pin's current value (the signal's, when it is netted).
            pub fn get(&self) -> $t {
                let from: fn($raw) -> $t = $from;
                // SAFETY: `slot` was registered by hal_pin_*_new, which stored a valid pointer
                // in it (HAL re-points it atomically on `net`/`unlinkp`, always at a live value
                // of this type in shared memory); the shared memory stays mapped while `_owner`
                // keeps the component from hal_exit. Volatile: the realtime side changes both.
                from(unsafe {
                    let value: *mut $raw = std::ptr::read_volatile(self.slot.cast_const());
                    std::ptr::read_volatile(value.cast_const())
                })
            }

            /// Sets the pin's value (for output pins; HAL lets the owner write any pin).
            pub fn set(&self, value: $t) {
                let to: fn($t) -> $raw = $to;
                let raw = to(value);
                // SAFETY: as in `get`: the slot holds a valid, aligned pointer to this pin's
                // value in mapped HAL shared memory; HAL values are plain words written
                // without locks by design (one writer per signal).
                unsafe {
                    let value: *mut $raw = std::ptr::read_volatile(self.slot.cast_const());
                    std::ptr::write_volatile(value, raw)
                }
            }
        }

        impl Clone for $pin {
            /// Another handle on the same pin (both read and write the same HAL value).
            fn clone(&self) -> Self {
                Self {
                    slot: self.slot,
                    _owner: Arc::clone(&self._owner),
                }
            }
        }

        impl fmt::Debug for $pin {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.debug_struct(stringify!($pin))
                    .field("value", &self.get())
                    .finish()
            }
        }

        // SAFETY: a pin is a pointer into process-wide HAL shared memory that any thread may
        // access (HAL itself is shared with other processes and the realtime thread); the
        // `Arc<Inner>` it holds is Send + Sync. Moving a pin to the cycle thread is sound.
        unsafe impl Send for $pin {}
    };
}

pin_access!(FloatPin, f64, f64, |v| v, |v| v);
pin_access!(BitPin, bool, u8, |v| v != 0, u8::from);
pin_access!(S32Pin, i32, i32, |v| v, |v| v);

/// Runs the calling thread under the `SCHED_FIFO` policy at `priority` (1–99) and locks the
/// process' memory (`mlockall`), so that the cycle is not delayed by ordinary processes or page
/// faults. Needs root or `CAP_SYS_NICE`/`CAP_IPC_LOCK`; the error names the call that failed.
pub fn set_realtime_priority(priority: i32) -> Result<(), String> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: `param` is an initialised sched_param on the stack that outlives the call;
    // pid 0 means the calling thread; the call changes nothing but its scheduling.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc != 0 {
        return Err(format!(
            "sched_setscheduler(SCHED_FIFO, {priority}): {}",
            std::io::Error::last_os_error()
        ));
    }
    // SAFETY: mlockall takes flags only and affects the process' paging, not memory contents.
    let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if rc != 0 {
        return Err(format!("mlockall: {}", std::io::Error::last_os_error()));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Timing: the few libc calls a periodic userspace cycle needs beyond `std` (the safe pacing
// and measurement built on them is in `crate::pacer` and `crate::host`).
// ---------------------------------------------------------------------------------------------

/// Reads a clock in ns.
fn clock_ns(clock: libc::clockid_t) -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec on the stack; clock_gettime only writes it.
    // The clocks used here (monotonic, process and thread CPU time) exist on every Linux, so
    // the call cannot fail; a zeroed `ts` would be the answer if it did.
    unsafe { libc::clock_gettime(clock, &mut ts) };
    (ts.tv_sec as u64).saturating_mul(1_000_000_000) + ts.tv_nsec as u64
}

/// `CLOCK_MONOTONIC` in ns: the clock of [`sleep_until_ns`] (and of `std::time::Instant` on
/// Linux).
pub fn monotonic_ns() -> u64 {
    clock_ns(libc::CLOCK_MONOTONIC)
}

/// CPU time used by the whole process (every thread) in ns (`CLOCK_PROCESS_CPUTIME_ID`).
pub fn process_cpu_ns() -> u64 {
    clock_ns(libc::CLOCK_PROCESS_CPUTIME_ID)
}

/// CPU time used by the calling thread in ns (`CLOCK_THREAD_CPUTIME_ID`).
pub fn thread_cpu_ns() -> u64 {
    clock_ns(libc::CLOCK_THREAD_CPUTIME_ID)
}

/// Sleeps until `CLOCK_MONOTONIC` reads `deadline_ns`: `clock_nanosleep` with `TIMER_ABSTIME`,
/// so that the time between computing the deadline and going to sleep (or a preemption in
/// between) does not shift the wake-up, as a relative sleep would. Returns at once if the
/// deadline has passed; resumes the sleep after a signal.
pub fn sleep_until_ns(deadline_ns: u64) {
    let ts = libc::timespec {
        tv_sec: (deadline_ns / 1_000_000_000) as libc::time_t,
        tv_nsec: (deadline_ns % 1_000_000_000) as libc::c_long,
    };
    loop {
        // SAFETY: `ts` is a valid timespec; with TIMER_ABSTIME the remaining-time pointer is
        // unused and may be null.
        let rc = unsafe {
            libc::clock_nanosleep(
                libc::CLOCK_MONOTONIC,
                libc::TIMER_ABSTIME,
                &ts,
                std::ptr::null_mut(),
            )
        };
        // clock_nanosleep returns the error number itself (not -1 and errno).
        if rc != libc::EINTR {
            return;
        }
    }
}

/// Binds the calling thread to one CPU (`sched_setaffinity`), so that the cycle keeps its
/// caches and is not migrated between CPUs.
pub fn pin_to_cpu(cpu: usize) -> Result<(), String> {
    bind_to_cpus(&[cpu])
}

/// Binds the calling thread to a set of CPUs (`sched_setaffinity`); threads it starts later
/// inherit the set.
pub fn bind_to_cpus(cpus: &[usize]) -> Result<(), String> {
    // SAFETY: cpu_set_t is a plain bit array for which all-zero is the empty set.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    for &cpu in cpus {
        if cpu >= libc::CPU_SETSIZE as usize {
            return Err(format!("CPU {cpu} is beyond CPU_SETSIZE"));
        }
        // SAFETY: `cpu` < CPU_SETSIZE was checked above, so CPU_SET stays inside `set`.
        unsafe { libc::CPU_SET(cpu, &mut set) };
    }
    // SAFETY: `set` is an initialised cpu_set_t of the size passed; pid 0 is the calling thread.
    let rc = unsafe { libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) };
    if rc != 0 {
        return Err(format!(
            "sched_setaffinity({cpus:?}): {}",
            std::io::Error::last_os_error()
        ));
    }
    Ok(())
}

/// Sets the calling thread's timer slack (`PR_SET_TIMERSLACK`): the kernel may otherwise
/// delay a normal thread's timer wake-ups by up to 50 µs to batch them (realtime threads
/// have none).
pub fn set_timer_slack_ns(ns: u64) -> Result<(), String> {
    // SAFETY: PR_SET_TIMERSLACK takes one integer argument and changes only the thread's slack.
    let rc = unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, ns as libc::c_ulong, 0, 0, 0) };
    if rc != 0 {
        return Err(format!(
            "prctl(PR_SET_TIMERSLACK): {}",
            std::io::Error::last_os_error()
        ));
    }
    Ok(())
}
