//! The process keeps memory it frees (`meshvet::pages::keep_freed_memory`), so the next big array
//! does not pay the kernel's faults and zeroing again. Its own test binary: the allocator's
//! settings are process-wide, and the resident size must not move with other tests.

/// The process's resident memory in pages, from `statm` (`/proc/self/statm`, opened before), read
/// without allocating: an allocation between freeing one array and taking the next would be cut
/// from the freed block.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn resident(statm: &std::fs::File) -> usize {
    use std::os::unix::fs::FileExt;
    let mut buffer = [0u8; 256];
    let n = statm.read_at(&mut buffer, 0).expect("/proc/self/statm");
    let text = std::str::from_utf8(&buffer[..n]).expect("text");
    text.split_whitespace().nth(1).unwrap().parse().unwrap()
}

/// A freed 16 MiB array stays resident (glibc's defaults map a block that size on its own and
/// unmap it when freed, giving it all back to the kernel), and the next one of that size is
/// served from it without growing the process.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[test]
fn freed_arrays_stay_with_the_process() {
    meshvet::pages::keep_freed_memory();
    // SAFETY: sysconf only reads a system constant.
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) } as usize;
    let statm = std::fs::File::open("/proc/self/statm").expect("/proc/self/statm");
    const SIZE: usize = 16 << 20;
    let array = std::hint::black_box(vec![1u8; SIZE]);
    let full = resident(&statm) * page;
    drop(array);
    let after_free = resident(&statm) * page;
    let again = std::hint::black_box(vec![2u8; SIZE]);
    let refilled = resident(&statm) * page;
    drop(again);
    assert!(
        after_free + SIZE / 4 > full,
        "resident {full} -> {after_free} bytes: the freed array went back to the kernel"
    );
    assert!(
        refilled < full + SIZE / 4,
        "resident {full} -> {refilled} bytes: the second array did not reuse the first's memory"
    );
}
