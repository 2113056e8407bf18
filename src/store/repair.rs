//! Which finished segments of a run a resumed forward stage keeps, which steps it
//! recomputes, and setting aside the rest.
//!
//! A killed run leaves at most one unfinished segment, which is discarded; a damaged disk or
//! a hand that moved files can leave damaged, missing or misnamed segments anywhere. Only
//! the steps they held are recomputed, from the checkpoint before them (the dynamics is
//! deterministic, so bit for bit): damage early in a week-long run costs the steps of its
//! segment, not the days after it.
//! Nothing readable is deleted before its replacement is written: damaged segments are kept
//! as `.corrupt`; intact ones a repair has to rewrite after all (see `forward_run`) as
//! `.superseded` until it has.

use super::records::{Checkpoint, Stats};
use super::run::{gap_between, r_every_step_between, RunDir, SegmentFile, StoreConfig};
use crate::config::RunConfig;
use super::schema::{CHECKPOINT, STATS};
use super::segment::{read_segment, ReadMode, RUN_METADATA};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// The directory a repair writes the steps it recomputes into, until they are verified
/// (`forward_run`): segments there are never the run's. A repair that was stopped goes on
/// from the newest of them ([`staged_chain`]).
pub const UNVERIFIED: &str = "repair-unverified";

/// Remove the segments a killed run left unfinished (`.tmp`), saying what each held: the
/// run continues from a finished segment's checkpoint, and recomputes what they held. So
/// does a repair from the finished segments it had written aside.
pub fn discard_partial_segments(dir: &RunDir, notice: &mut dyn FnMut(String)) -> Result<()> {
    let unverified = RunDir { path: dir.path.join(UNVERIFIED) };
    if unverified.path.is_dir() {
        discard_partial_segments(&unverified, notice)?;
    }
    for partial in dir.partial_segments()? {
        let mut checkpoints = 0u64;
        let mut last = None;
        let report = read_segment(&partial, ReadMode::Salvage, |m| {
            if m.topic == CHECKPOINT.topic {
                checkpoints += 1;
                last = Some(m.step);
            }
            Ok(())
        });
        let what = match (report, last) {
            (Ok(_), Some(step)) => format!("{checkpoints} complete checkpoints up to step {step}"),
            _ => "no complete checkpoint".to_string(),
        };
        notice(format!("discarding the interrupted segment {} ({what}); they will be recomputed", partial.display()));
        std::fs::remove_file(&partial).map_err(|e| Error::io(&partial, e))?;
    }
    Ok(())
}

/// What a resume keeps of the finished segments, and what it recomputes.
pub struct Triage {
    /// Steps no intact segment holds, with an intact segment after them, oldest first: each
    /// is recomputed on its own.
    pub holes: Vec<Hole>,
    /// The last checkpoint of the newest intact segment: the run continues from it.
    pub newest_intact: Option<LastCheckpoint>,
    /// Intact segments an interrupted repair set aside, deleted once the run is whole.
    pub superseded: Vec<PathBuf>,
    /// Damaged or misnamed segments set aside now.
    pub set_aside: usize,
}

/// Steps of a run no intact segment holds, between two that do.
#[derive(Debug)]
pub struct Hole {
    /// The intact segment before the hole, whose last checkpoint the recomputation starts
    /// from; None where there is none (it starts from step 0).
    pub after: Option<SegmentFile>,
    /// The last step to write: where the segment before `next` ended
    /// ([`StoreConfig::last_write_before`]).
    pub until: u64,
    /// The intact segment after the hole: its first checkpoint is what the recomputation
    /// must arrive at, bit for bit.
    pub next: SegmentFile,
}

/// Read every finished segment whole (CRCs checked), set the damaged ones aside as
/// `.corrupt`, and find the steps no intact segment holds: the holes the damaged segments
/// leave, and gaps (a segment moved out or deleted), which the backward stage would stop
/// at. A hole between two intact segments is recomputed on its own, from the last
/// checkpoint before it: the dynamics is deterministic, so the new files hold the numbers
/// of the old, bit for bit (only wall times differ), and the recomputation must arrive at
/// the next segment's first checkpoint exactly (see `forward_run`). After the newest intact
/// segment the run simply continues.
///
/// Before the first segment only the checkpoints from where the backward stage starts
/// (`StoreConfig::window_start`) on are needed; older ones are pruned by design, and so
/// are the segments the rules of pruning would delete now (after an extension, the old
/// window), before any hole is looked for. Where the needed checkpoints are missing, there
/// is no checkpoint before them, and the hole is recomputed from step 0.
///
/// A segment whose steps are not those its name says ([`SegmentFile::misnamed`]: renamed,
/// or copied in under another name) is set aside the same way, and only the hole it may
/// leave is recomputed: a stray copy costs nothing, two swapped names their own steps. A
/// segment whose steps the one before it holds too (a copy put back beside a repaired run)
/// is set aside as `.superseded`.
pub fn triage(dir: &RunDir, store: &StoreConfig, config: &RunConfig, notice: &mut dyn FnMut(String)) -> Result<Triage> {
    let c = store.checkpoint_every.max(1);
    let needed = store.first_needed_checkpoint(config);
    let mut intact: Vec<SegmentFile> = Vec::new();
    // Damaged and misnamed segments, set aside: the names of the damaged ones say where the
    // segments that replace them end, and their notices wait until it is known what is
    // recomputed.
    let mut damaged: Vec<SetAside> = Vec::new();
    // Every segment is read before any is moved: a file that cannot be read stops the
    // resume with nothing changed.
    let mut reads = Vec::new();
    for seg in dir.segments()? {
        let read = match read_last(&seg.path) {
            // Not damage (permissions, a failing disk): recomputing it would cost hours for
            // nothing.
            Err(e @ Error::Io { .. }) => {
                return Err(Error::Other(format!("{e}; nothing was changed: make the file readable (its permissions, the disk) and resume again")));
            }
            Err(e) => Err((e.to_string(), false)),
            Ok((held, _)) => seg.misnamed(Some(held)).map_or(Ok(()), |why| Err((why, true))),
        };
        reads.push((seg, read));
    }
    for (seg, read) in reads {
        match read {
            Ok(()) => intact.push(seg),
            Err((why, misnamed)) => {
                let aside = corrupt_aside(&seg.path);
                std::fs::rename(&seg.path, &aside).map_err(|e| Error::io(&seg.path, e))?;
                damaged.push(SetAside { seg, why, aside, misnamed });
            }
        }
    }
    let mut superseded: Vec<PathBuf> = std::fs::read_dir(&dir.path)
        .map_err(|e| Error::io(&dir.path, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.to_string_lossy().ends_with(".mcap.superseded"))
        .collect();
    let mut kept: Vec<SegmentFile> = Vec::with_capacity(intact.len());
    for seg in intact {
        match kept.last() {
            Some(before) if seg.last <= before.last => {
                let aside = seg.path.with_extension("mcap.superseded");
                notice(format!("{} holds steps {} holds too; moving it aside to {}", seg.path.display(), before.path.display(), aside.display()));
                std::fs::rename(&seg.path, &aside).map_err(|e| Error::io(&seg.path, e))?;
                superseded.push(aside);
            }
            _ => kept.push(seg),
        }
    }
    let pruned = super::sink::prune(&dir.path, needed, store.keep_segments)?;
    kept.retain(|s| !pruned.contains(&s.path));
    let inside = |a: u64, b: u64| damaged.iter().filter(|d| !d.misnamed && a < d.seg.first && d.seg.last < b).map(|d| d.seg.last).max();
    let leading = kept.first().filter(|s| s.first > needed).map(|s| (None, s));
    let between = kept.windows(2).filter(|w| gap_between(w[0].last, w[1].first, c, r_every_step_between(&w[0], &w[1])) || inside(w[0].last, w[1].first).is_some()).map(|w| (Some(&w[0]), &w[1]));
    let holes: Vec<Hole> = leading
        .into_iter()
        .chain(between)
        .map(|(before, next)| Hole {
            after: before.cloned(),
            // The damaged file's name, where it ends off the grid (at a stop), or the last step
            // before `next` that the run writes, where more than that file is missing.
            until: inside(before.map_or(0, |s| s.last), next.first).unwrap_or(0).max(store.last_write_before(next.first, config)),
            next: next.clone(),
        })
        .collect();
    for SetAside { seg, why, aside, misnamed } in &damaged {
        let from_zero = kept.is_empty() || holes.iter().any(|h| h.after.is_none() && seg.first < h.next.first);
        let fate = if *misnamed {
            "the steps it holds are recomputed where no other segment holds them".to_string()
        } else if from_zero {
            "its steps are recomputed from step 0, as no checkpoint before them is kept".to_string()
        } else if kept.first().is_some_and(|s| seg.last < s.first) {
            format!("its steps come before step {needed}, from where the backward stage needs checkpoints, and are not recomputed")
        } else {
            "its steps are recomputed from the checkpoint before it".to_string()
        };
        notice(format!("{why}; moving it aside to {} ({fate})", aside.display()));
    }
    let newest_intact = match kept.last() {
        Some(seg) => Some(read_last(&seg.path)?.1),
        None => None,
    };
    Ok(Triage { holes, newest_intact, superseded, set_aside: damaged.len() })
}

/// A damaged or misnamed segment moved aside (to `aside`), and why.
struct SetAside {
    seg: SegmentFile,
    why: String,
    aside: PathBuf,
    /// Its steps are not those its name says: the name bounds no hole.
    misnamed: bool,
}

/// The newest segment a stopped recomputation of `hole` wrote into `staging` (all of them
/// read back whole), to go on from; None, with `staging` emptied, where there is none or
/// what is there is not one unbroken stretch of the hole's steps (another hole's, say).
pub fn staged_chain(staging: &Path, hole: &Hole, checkpoint_every: u64, notice: &mut dyn FnMut(String)) -> Result<Option<(SegmentFile, LastCheckpoint)>> {
    if !staging.is_dir() {
        return Ok(None);
    }
    let segs = RunDir { path: staging.to_path_buf() }.segments()?;
    let start = hole.after.as_ref().map(|a| a.last);
    let unbroken = segs.windows(2).all(|w| !gap_between(w[0].last, w[1].first, checkpoint_every, None));
    let inside = segs.iter().all(|s| s.last <= hole.until && start.is_none_or(|a| s.first > a));
    let joined = match (start, segs.first()) {
        (Some(a), Some(first)) => !gap_between(a, first.first, checkpoint_every, None),
        _ => true,
    };
    let newest = match segs.last() {
        Some(newest) if unbroken && inside && joined => read_last(&newest.path).ok().map(|(_, last)| (newest.clone(), last)),
        _ => None,
    };
    if newest.is_none() && !segs.is_empty() {
        notice(format!("discarding {}: it holds steps of another recomputation than the one due now", staging.display()));
    }
    if newest.is_none() {
        std::fs::remove_dir_all(staging).map_err(|e| Error::io(staging, e))?;
    }
    Ok(newest)
}

/// Set aside the intact segments from `next` on (after a hole whose recomputation did not
/// arrive at `next`'s first checkpoint): they are recomputed with the rest of the run, and
/// kept as `.superseded` until then. Returns the paths they are kept at.
pub fn supersede_from(dir: &RunDir, next: &SegmentFile, notice: &mut dyn FnMut(String)) -> Result<Vec<PathBuf>> {
    let mut kept = Vec::new();
    for seg in dir.segments()?.into_iter().filter(|s| s.first >= next.first) {
        let aside = seg.path.with_extension("mcap.superseded");
        notice(format!("{} is recomputed with the rest of the run (kept as {} until then)", seg.path.display(), aside.display()));
        std::fs::rename(&seg.path, &aside).map_err(|e| Error::io(&seg.path, e))?;
        kept.push(aside);
    }
    Ok(kept)
}

/// What the newest intact segment says about where the run stands.
pub struct LastCheckpoint {
    pub checkpoint: Checkpoint,
    pub stats: Stats,
}

/// Where a damaged segment is kept: FILE.corrupt, or FILE.2.corrupt, ... where an earlier
/// damaged segment of the same name is kept already (a second damage must not replace it).
fn corrupt_aside(path: &Path) -> PathBuf {
    let mut aside = path.with_extension("mcap.corrupt");
    let mut i = 1;
    while aside.symlink_metadata().is_ok() {
        i += 1;
        aside = path.with_extension(format!("{i}.mcap.corrupt"));
    }
    aside
}

/// The last checkpoint and stats of a finished segment, reading it whole (CRCs checked),
/// with the steps the writer named it by: those of its first message and its last checkpoint.
pub fn read_last(path: &Path) -> Result<((u64, u64), LastCheckpoint)> {
    let (mut first, mut cp, mut stats) = (None, None, None);
    read_segment(path, ReadMode::Strict, |m| {
        let bad = |e: String| Error::corrupt(path, format!("step {}: {e}", m.step));
        if m.topic != RUN_METADATA {
            first.get_or_insert(m.step);
        }
        if m.topic == CHECKPOINT.topic {
            cp = Some((m.step, Checkpoint::decode(m.data).map_err(bad)?));
        } else if m.topic == STATS.topic {
            stats = Some(Stats::decode(m.data).map_err(bad)?);
        }
        Ok(())
    })?;
    match (first, cp, stats) {
        (Some(first), Some((last, checkpoint)), Some(stats)) if stats.step == checkpoint.state.step => Ok(((first, last), LastCheckpoint { checkpoint, stats })),
        _ => Err(Error::corrupt(path, "no complete checkpoint with its statistics")),
    }
}

/// The last two checkpoints of a finished segment, older first (read whole, CRCs checked);
/// one where it holds only one.
pub fn last_checkpoints(path: &Path) -> Result<Vec<Checkpoint>> {
    let mut kept: Vec<Vec<u8>> = Vec::new();
    read_segment(path, ReadMode::Strict, |m| {
        if m.topic == CHECKPOINT.topic {
            if kept.len() == 2 {
                kept.remove(0);
            }
            kept.push(m.data.to_vec());
        }
        Ok(())
    })?;
    kept.iter().map(|data| Checkpoint::decode(data).map_err(|e| Error::corrupt(path, e))).collect()
}

/// The first checkpoint of a finished segment (read whole, CRCs checked).
pub fn first_checkpoint(path: &Path) -> Result<Checkpoint> {
    let mut first = None;
    read_segment(path, ReadMode::Strict, |m| {
        if m.topic == CHECKPOINT.topic && first.is_none() {
            first = Some(Checkpoint::decode(m.data).map_err(|e| Error::corrupt(path, format!("step {}: {e}", m.step)))?);
        }
        Ok(())
    })?;
    first.ok_or_else(|| Error::corrupt(path, "no checkpoint"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A second damaged segment of one name is kept beside the first, not over it.
    #[test]
    fn damaged_segments_of_one_name_are_all_kept() {
        let dir = std::env::temp_dir().join(format!("clv-corrupt-aside-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let seg = dir.join("seg-000000000000-000000000100.mcap");
        assert_eq!(corrupt_aside(&seg), dir.join("seg-000000000000-000000000100.mcap.corrupt"));
        std::fs::write(dir.join("seg-000000000000-000000000100.mcap.corrupt"), b"first").unwrap();
        assert_eq!(corrupt_aside(&seg), dir.join("seg-000000000000-000000000100.2.mcap.corrupt"));
        std::fs::write(dir.join("seg-000000000000-000000000100.2.mcap.corrupt"), b"second").unwrap();
        assert_eq!(corrupt_aside(&seg), dir.join("seg-000000000000-000000000100.3.mcap.corrupt"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
