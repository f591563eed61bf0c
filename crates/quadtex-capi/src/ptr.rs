//! Pointer conversions at the C boundary. With the exported functions'
//! `#[unsafe(no_mangle)]` attributes, this module holds all of the crate's
//! unsafe code: each helper checks what can be checked (NULL, alignment,
//! size) and documents what the C caller must guarantee for the rest.
#![allow(unsafe_code)]

use std::ffi::{CStr, c_char};
use std::marker::PhantomData;
use std::path::PathBuf;
use std::ptr::NonNull;

use crate::error::Failure;

/// Refuses NULL and misaligned pointers, naming the argument.
fn check<T>(ptr: *const T, name: &str) -> Result<(), Failure> {
    if ptr.is_null() {
        return Err(Failure::invalid(format!("{name} is NULL")));
    }
    if !ptr.is_aligned() {
        return Err(Failure::invalid(format!(
            "{name} is not aligned to {} bytes",
            std::mem::align_of::<T>()
        )));
    }
    Ok(())
}

/// Refuses `len` elements of `T` that would span more than `isize::MAX` bytes.
fn check_len<T>(len: usize, name: &str) -> Result<(), Failure> {
    match len.checked_mul(std::mem::size_of::<T>()) {
        Some(bytes) if bytes <= isize::MAX as usize => Ok(()),
        _ => Err(Failure::invalid(format!(
            "{name}: {len} elements do not fit in memory"
        ))),
    }
}

/// The NUL-terminated string `ptr` as a path (argument `name` in errors).
///
/// # Safety
/// `ptr` is NULL or points to a NUL-terminated string readable until this
/// function returns.
pub(crate) unsafe fn path_arg(ptr: *const c_char, name: &str) -> Result<PathBuf, Failure> {
    check(ptr, name)?;
    // SAFETY: `ptr` is not NULL (checked) and, by this function's contract,
    // points to a readable NUL-terminated string; the bytes are copied into
    // the returned path before returning.
    let bytes = unsafe { CStr::from_ptr(ptr) }.to_bytes();
    crate::ops::bytes_to_path(bytes, name)
}

/// The `len` elements at `ptr` (argument `name` in errors); `ptr` may be
/// NULL when `len` is 0.
///
/// # Safety
/// Unless `ptr` is NULL or `len` is 0, `ptr` points to `len` initialised
/// `T`s that nothing writes to during `'a`.
pub(crate) unsafe fn slice_arg<'a, T>(
    ptr: *const T,
    len: usize,
    name: &str,
) -> Result<&'a [T], Failure> {
    if len == 0 {
        return Ok(&[]);
    }
    check(ptr, name)?;
    check_len::<T>(len, name)?;
    // SAFETY: non-NULL, aligned and at most isize::MAX bytes long (checked);
    // readable, initialised and unaliased by writers for 'a by contract.
    Ok(unsafe { std::slice::from_raw_parts(ptr, len) })
}

/// The `len` elements at `ptr`, writable (argument `name` in errors); `ptr`
/// may be NULL when `len` is 0.
///
/// # Safety
/// Unless `ptr` is NULL or `len` is 0, `ptr` points to `len` writable `T`s
/// (any bit pattern valid, as for floats) that nothing else reads or writes
/// during `'a`.
pub(crate) unsafe fn slice_mut_arg<'a, T>(
    ptr: *mut T,
    len: usize,
    name: &str,
) -> Result<&'a mut [T], Failure> {
    if len == 0 {
        return Ok(&mut []);
    }
    check(ptr.cast_const(), name)?;
    check_len::<T>(len, name)?;
    // SAFETY: non-NULL, aligned and at most isize::MAX bytes long (checked);
    // valid and exclusively ours for 'a by contract.
    Ok(unsafe { std::slice::from_raw_parts_mut(ptr, len) })
}

/// The object at `ptr`, or `None` for NULL (argument `name` in errors).
///
/// # Safety
/// `ptr` is NULL or points to a valid `T` that nothing writes to during `'a`.
pub(crate) unsafe fn optional_ref_arg<'a, T>(
    ptr: *const T,
    name: &str,
) -> Result<Option<&'a T>, Failure> {
    if ptr.is_null() {
        return Ok(None);
    }
    check(ptr, name)?;
    // SAFETY: non-NULL and aligned (checked); valid and not written to for
    // 'a by contract.
    Ok(Some(unsafe { &*ptr }))
}

/// The object at `ptr`, which must not be NULL (argument `name` in errors).
///
/// # Safety
/// As [`optional_ref_arg`].
pub(crate) unsafe fn ref_arg<'a, T>(ptr: *const T, name: &str) -> Result<&'a T, Failure> {
    // SAFETY: same contract, passed on.
    unsafe { optional_ref_arg(ptr, name) }?
        .ok_or_else(|| Failure::invalid(format!("{name} is NULL")))
}

/// An output parameter: a place the function writes its result to.
pub(crate) struct Out<'a, T> {
    ptr: NonNull<T>,
    _place: PhantomData<&'a mut T>,
}

impl<'a, T> Out<'a, T> {
    /// The output parameter `ptr` (argument `name` in errors).
    ///
    /// # Safety
    /// `ptr` is NULL or valid for writes of a `T` during `'a` (its current
    /// contents, possibly uninitialised, are never read nor dropped).
    pub(crate) unsafe fn new(ptr: *mut T, name: &str) -> Result<Out<'a, T>, Failure> {
        check(ptr.cast_const(), name)?;
        let ptr = NonNull::new(ptr).ok_or_else(|| Failure::invalid(format!("{name} is NULL")))?;
        Ok(Out {
            ptr,
            _place: PhantomData,
        })
    }

    /// Stores `value` (without reading or dropping what was there).
    pub(crate) fn set(&mut self, value: T) {
        // SAFETY: valid for writes and aligned, by `Out::new`'s contract and
        // checks.
        unsafe { self.ptr.as_ptr().write(value) }
    }
}

/// Moves `value` to the heap and hands ownership to C.
pub(crate) fn into_raw<T>(value: T) -> *mut T {
    Box::into_raw(Box::new(value))
}

/// Takes back ownership of what [`into_raw`] handed out, and drops it; NULL
/// is ignored.
///
/// # Safety
/// `ptr` is NULL or was returned by [`into_raw`] (with the same `T`) and
/// has not been released since; nothing uses it afterwards.
pub(crate) unsafe fn release<T>(ptr: *mut T) {
    if !ptr.is_null() {
        // SAFETY: by contract, `ptr` came from `Box::into_raw` and is owned
        // by no one else.
        drop(unsafe { Box::from_raw(ptr) });
    }
}
