//! The process keeps memory it frees (`meshvet::pages::keep_freed_memory`), so the next big array
//! does not pay the kernel's faults and zeroing again. Its own test binary: the allocator's
//! settings are process-wide, and the resident size must not move with other tests (the tests
//! here take turns, [`ONE_AT_A_TIME`]).

/// Held by each test for its whole run.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

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
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
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

/// The minor page faults this thread has taken so far.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn faults() -> i64 {
    // SAFETY: `rusage` is plain data; `getrusage` fills it.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_THREAD, &mut usage) };
    usage.ru_minflt
}

/// Large zeroed blocks kept in a heap fault in as huge pages: the allocator's own zeroing must not
/// touch them before the advice. glibc's `calloc` zeroes a block that starts a new thread heap
/// itself, and so faulted it in 4 KiB pages (on an 871k-face scan, 5,900 of its 10,500 faults).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[test]
fn large_zeroed_blocks_fault_in_huge_pages() {
    use meshvet::pages::HugePages;
    use std::alloc::{GlobalAlloc, Layout};
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    if std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled")
        .map_or(true, |s| s.contains("[never]"))
    {
        return;
    }
    meshvet::pages::keep_freed_memory();
    let size = 20 << 20;
    let layout = Layout::from_size_align(size, 8).unwrap();
    // On a thread of its own, as a scan's worker allocates: four blocks cannot share one 64 MiB
    // thread heap, so at least one starts a new heap.
    let faults_each = std::thread::spawn(move || {
        let mut blocks = Vec::new();
        let mut taken = Vec::new();
        for _ in 0..4 {
            let before = faults();
            // SAFETY: a non-zero size; the block is used as `size` bytes and freed with `layout`.
            let block = unsafe {
                let p = HugePages.alloc_zeroed(layout);
                assert!(!p.is_null());
                std::slice::from_raw_parts_mut(p, size)
            };
            block.iter_mut().step_by(4096).for_each(|b| *b += 1);
            taken.push(faults() - before);
            assert!(block.iter().step_by(4096).all(|&b| b == 1));
            blocks.push(block.as_mut_ptr());
        }
        for p in blocks {
            // SAFETY: allocated above with this layout.
            unsafe { HugePages.dealloc(p, layout) };
        }
        taken
    })
    .join()
    .unwrap();
    // A block is 5,120 small pages; on huge pages only its two ends (at most 1,024) are small.
    // Half the small pages leaves room for a kernel short of huge pages.
    assert!(faults_each.iter().all(|&f| f < 2_560), "{faults_each:?}");
}
