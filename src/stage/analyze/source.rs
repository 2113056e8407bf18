//! What `clv analyze` reads: a frame file, a stream on standard input, or a run directory,
//! which stands for the frame file of its last backward sweep. The errors here say which
//! source was meant and how to make the frames it lacks, since a report of the wrong frames
//! (an earlier sweep's file, another run's) would look like a right one.

use crate::stage::backward::{rewrite_advice, BackwardOptions, SweepFile};
use super::{select, Analysed, Analyzer, Context};
use crate::error::{Error, Result};
use crate::store::frames::StreamInfo;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A run directory stands for the frame file its last backward sweep wrote (its `--out`).
/// Where that sweep wrote none (a stream, `--save-every 0`), has not finished it, or its
/// file is gone, the run is refused, naming the sweep: a frames.mcap left by an earlier sweep
/// is not this one's frames. A run without a sweep record (or one of a build before them)
/// stands for the frames.mcap in it.
fn frame_source(source: &Path) -> Result<(PathBuf, Option<SweepFile>)> {
    if !source.is_dir() {
        return Ok((source.to_path_buf(), None));
    }
    let expect = |options: Option<BackwardOptions>| -> Result<Option<SweepFile>> {
        let (dir, meta) = crate::store::RunDir::open(source)?;
        // A run.json that no longer describes the run is its own error, not the frames'.
        dir.check_meta(&meta)?;
        Ok(Some(SweepFile { dir: source.to_path_buf(), meta, options }))
    };
    let d = source.display();
    let frames = crate::store::RunDir { path: source.to_path_buf() }.frames_path();
    let record = crate::store::RunDir { path: source.to_path_buf() }.progress_path();
    let last = crate::store::progress::last_sweep(source).map_err(|e| {
        Error::Other(format!("{e}; the run's last backward sweep is unknown, so {d} cannot stand for its frames: name a frame file (`clv analyze FILE --out REPORT`), or write one with `clv backward {d} --out FILE.mcap`"))
    })?;
    let Some(last) = last else {
        if frames.exists() {
            return Ok((frames, expect(None)?));
        }
        if !source.join("run.json").exists() {
            let what = if source.join("index.html").exists() { "a report (what `clv analyze` writes)" } else { "no run directory" };
            return Err(Error::Other(format!("{d} is {what}: give a frame file (`clv analyze FILE --out REPORT`), a run directory whose backward stage wrote one, or - for a stream on standard input")));
        }
        // A forward run not yet finished has no backward stage to ask for.
        let run = crate::store::RunDir { path: source.to_path_buf() };
        if let Some(steps) = crate::store::RunDir::open(source).ok().map(|(_, meta)| meta.config.steps).filter(|&s| run.extension_interrupted(s)) {
            return Err(Error::Other(format!(
                "{d}: an extension of this run was interrupted (the results of the run before it are in {}): give the extension's command again \
                 (`clv forward --resume {d} --steps M` with its new length M), then run its backward stage",
                run.previous_results(steps).display()
            )));
        }
        if !run.spectrum_path().exists() {
            return Err(Error::Other(format!(
                "{d} is a forward run that has not finished (no spectrum.json yet), so it has no frames: finish it with `clv forward --resume {d}`, then run its backward stage (`clv backward {d} --out - | clv analyze - --out REPORT`)"
            )));
        }
        return Err(Error::Other(format!(
            "{d} is a directory without a frame file ({}); analyse a run with `clv backward {d} --out - | clv analyze - --out REPORT`, or write {} with `clv backward {d}` first",
            frames.display(),
            frames.display()
        )));
    };
    let opts = &last.options;
    let file = opts.frames_file(source);
    if let Some(file) = file.as_ref().filter(|f| last.done && f.exists()) {
        return Ok((file.clone(), expect(Some(last.options.clone()))?));
    }
    let flags = format!("recorded in {}: {}", record.display(), opts.as_flags());
    if let Some(f) = file.as_ref().filter(|_| !last.done) {
        let running = crate::store::RunDir { path: source.to_path_buf() }.is_being_written();
        let then = match running {
            true => "a clv process is writing it now: analyse the run when it has finished".to_string(),
            false => format!("continue it with `clv backward {d} --resume`, then analyse the run again"),
        };
        return Err(Error::Other(format!("{d}: the run's last backward sweep ({flags}) has not finished writing {}; {then}", f.display())));
    }
    let what = match &file {
        Some(f) => format!(
            "wrote {}, which is gone (deleted or moved; if it is only elsewhere now, such as under another mount point on another node, analyse it by name: `clv analyze FILE --out REPORT`)",
            f.display()
        ),
        None if opts.streams() => "streamed its frames to a reader (`--out -`, or the analyses of `clv run`) and wrote no frame file".into(),
        None => "computed only the CLV spectrum (`--save-every 0`) and wrote no frame file".into(),
    };
    let other = if frames.exists() && file.as_ref() != Some(&frames) {
        format!("; {} is an earlier sweep's: analyse it by name if you want those frames (`clv analyze {} --out REPORT`)", frames.display(), frames.display())
    } else {
        String::new()
    };
    let write = if frames.exists() { source.join("NAME.mcap") } else { frames.clone() };
    // The same sweep again: GS vectors and V_n where it had them, into a stream (nothing on
    // disk, as `clv run` does it) or into a file, whose size is worth knowing first.
    let again = BackwardOptions { frames_path: Some(write.clone()), no_frames: false, save_every: 1, ..opts.clone() };
    let run = crate::store::RunDir::open(source).ok();
    let mut same = String::new();
    if opts.with_gs {
        same += " --with-gs";
    }
    if opts.vectors_every > 1 {
        same += &format!(" --vectors-every {}", opts.vectors_every);
    }
    if run.as_ref().is_some_and(|(_, meta)| meta.store.transient != opts.transient) {
        same += &format!(" --transient {}", opts.transient);
    }
    if opts.c_init == crate::stage::backward::CInit::Random {
        same += " --c-init random";
    }
    let size = run.map_or(String::new(), |(dir, meta)| format!(" (about {})", crate::store::run::human(crate::stage::backward::frame_file_bytes(&dir, &meta, &again))));
    Err(Error::Other(format!(
        "{d}: the run's last backward sweep ({flags}) {what}, so there are no frames of it to analyse. Analyse them as they are computed, with nothing written: \
         `clv backward {d}{same} --out - | clv analyze - --out REPORT`; or write a frame file with `clv backward {d}{same} --out {}`{size} and analyse the run again{other}",
        write.display()
    )))
}

/// Run every applicable analysis over the frames of `source` (a file, or "-" for standard
/// input) into `out`, calling `on_frame` with the count of frames read so far. Returns what
/// was produced and the number of frames read.
pub fn analyze_source(
    source: &Path,
    out: &Path,
    every: Option<u64>,
    j: Option<Vec<usize>>,
    deltas: Option<Vec<u64>>,
    only: &[String],
    on_frame: &mut dyn FnMut(u64),
) -> Result<Analysed> {
    let (source, expected) = frame_source(source)?;
    let source = &source;
    let info = std::cell::RefCell::new(StreamInfo::default());
    let mut analyzer: Option<Analyzer> = None;
    let name = if source == Path::new("-") { "<stdin>".to_string() } else { source.display().to_string() };
    // How to write a damaged file whole again, where the sweep that wrote it is known (from
    // its metadata, or as the run directory's last sweep).
    let rewrite = |info: &StreamInfo| -> String {
        let options = BackwardOptions::of_stream(info).or_else(|| expected.as_ref().and_then(|e| e.options.clone()));
        if source == Path::new("-") || options.is_none() {
            return String::new();
        }
        let run = expected.as_ref().map(|e| e.dir.clone()).or_else(|| options.as_ref()?.frames_path.as_deref().and_then(|r| crate::store::frames::run_dir_of(source, r)));
        format!("; {}", rewrite_advice(source, options.as_ref(), run.as_deref()))
    };
    let damage = crate::store::frames::read_frames_with(
        source,
        |i| {
            if let Some(expected) = &expected
                && let Err(why) = expected.check(&i)
            {
                let (d, f) = (expected.dir.display(), source.display());
                return Err(Error::Other(format!(
                    "{f} stands for the frames of {d}, but {why}: analyse the file by name if you mean its frames (`clv analyze {f} --out REPORT`), or write this run's with `clv backward {d} --out FILE.mcap` and analyse that"
                )));
            }
            *info.borrow_mut() = i;
            Ok(())
        },
        |frame| {
            if analyzer.is_none() {
                let ctx = Context::new(&info.borrow(), &frame, &name, every, j.clone(), deltas.clone())?;
                let analyses = select(&ctx, only)?;
                analyzer = Some(Analyzer::start(ctx, analyses, out)?);
            }
            let analyzer = analyzer.as_mut().expect("started");
            let flow = analyzer.feed(Arc::new(frame))?;
            on_frame(analyzer.frames);
            Ok(flow)
        },
    )
    .map_err(|e| match e {
        // Not a frame file at all (the run's, damaged from its start).
        Error::Corrupt { path, msg } if expected.is_some() => Error::Corrupt { msg: msg + &rewrite(&StreamInfo::default()), path },
        e => e,
    })?;
    let Some(analyzer) = analyzer else {
        return Err(Error::Other(match damage {
            Some(d) => format!("{name}: no frames in the stream ({d}){}", rewrite(&info.borrow())),
            None => format!("{name}: no frames in the stream: its writer sent none. It failed before its first frame (its own error says why: a full disk, a signal), or it was `clv backward --resume` of a sweep that had finished, which sends none (start it without --resume)"),
        }));
    };
    let analysed = analyzer.finish(damage.as_deref())?;
    if let Some(d) = damage {
        let rewrite = rewrite(&info.borrow());
        return Err(Error::corrupt(
            &name,
            format!("the stream ends early or is damaged ({d}); the {} complete frames before it were analysed into {}, but the results are incomplete{rewrite}", analysed.frames, out.display()),
        ));
    }
    Ok(analysed)
}
