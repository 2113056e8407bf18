//! The `clv` executable: process-wide memory settings, then the command line (src/cli).

mod cli;

/// One malloc arena for the whole process (glibc). With one arena per thread, the writer
/// thread's chunk buffers and the simulation's 5-8 MB checkpoint buffers fragment two heaps,
/// and resident memory crept up with run length: +8.6 % between 20 and 600 steps at D = 792,
/// +1.1 % with one arena (`clv bench`). The forward step allocates nothing and the others
/// little, so sharing the arena cost no measurable time (forward step 21.0 against 20.9 ms).
fn one_malloc_arena() {
    const M_ARENA_MAX: i32 = -8;
    mallopt(M_ARENA_MAX, 1); // before any other thread exists
}

/// glibc's mallopt(3); nothing elsewhere.
fn mallopt(param: i32, value: i32) {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        unsafe extern "C" {
            fn mallopt(param: i32, value: i32) -> i32;
        }
        // SAFETY: a plain call of glibc's mallopt with one of its documented parameters.
        unsafe { mallopt(param, value) };
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    let _ = (param, value);
}

/// Serve allocations of 1 MB and more from mmap, so that they go back to the system when
/// freed. For the forward stage only: it allocates its large buffers (checkpoint encodings,
/// the segment writer's chunks) at checkpoints, and from the heap their freed blocks
/// fragmented it, so that its peak memory crept with the segments written (52-56 MB for 20
/// steps against 56-58.5 MB for 200, with checkpoints every 5 steps in segments of 2;
/// 49.0-51.5 against 52.2-52.3 MB from mmap; 1030 steps of the paper's system took
/// 15.2-15.6 s against 14.7-15.6 s, the same within this machine's noise, with a peak of
/// 52-54 MB against 56-58 MB). The backward stage and
/// the analyses allocate a frame's vectors every step, where fresh mapped pages cost page
/// faults (a backward pipe took 4 % longer), so they keep glibc's default.
fn large_allocations_from_mmap() {
    const M_MMAP_THRESHOLD: i32 = -3;
    mallopt(M_MMAP_THRESHOLD, 1 << 20);
}

/// A file-size limit (`ulimit -f`, a batch system's) reached is an error of the write that
/// reaches it (EFBIG, named with its file, and the run resumes like after a full disk), not
/// SIGXFSZ, which kills the process without a word.
fn file_size_limit_as_an_error() {
    // SAFETY: setting a signal's disposition to ignore, before any other thread exists.
    unsafe { libc::signal(libc::SIGXFSZ, libc::SIG_IGN) };
}

/// The command line, refused with the argument named where it is not UTF-8 (a Latin-1
/// directory name, say) instead of the panic of `std::env::args`.
fn utf8_args() -> clv::error::Result<Vec<String>> {
    std::env::args_os()
        .enumerate()
        .map(|(i, a)| {
            a.into_string().map_err(|a| {
                clv::error::Error::Other(format!(
                    "argument {i} of the command line, {:?}, is not UTF-8, which clv takes its paths and values in: rename what it names, or reach it through a symbolic link with a UTF-8 name",
                    a.to_string_lossy()
                ))
            })
        })
        .collect()
}

fn main() {
    one_malloc_arena();
    file_size_limit_as_an_error();
    let result = utf8_args().and_then(cli::parse).and_then(|(cli, matches)| {
        if matches!(cli.command, cli::Command::Forward(_)) {
            large_allocations_from_mmap();
        }
        cli::execute(&cli, &matches)
    });
    if std::env::var_os("CLV_REPORT_PEAK_RSS").is_some()
        && let Some(kb) = clv::bench::peak_rss_kb() {
            clv::note!("clv-peak-rss-kb: {kb}");
        }
    if let Err(e) = result {
        clv::note!("clv: error: {e}");
        std::process::exit(e.exit_code());
    }
}
