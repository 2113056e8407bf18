//! `clv inspect`: what a run directory or a frame file holds, and whether it is intact.

use super::{emit, print_json};
use clap::Args;
use clv::report::inspect;
use clv::{Error, Result};
use std::path::PathBuf;

#[derive(Args)]
pub struct InspectArgs {
    /// A run directory, or a frame file written by `clv backward --out FILE`.
    pub dir: PathBuf,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
}

pub fn inspect(args: &InspectArgs) -> Result<()> {
    if args.dir.is_file() {
        let found = inspect::inspect_frames(&args.dir)?;
        print_inspection(&found, found.text(), args.json)?;
        // A sweep writes its frame file as FILE.tmp and renames it when done.
        let file = if found.unfinished { args.dir.with_extension("") } else { args.dir.clone() };
        let resume = format!(
            "`clv backward {} --out {} --resume` continues a sweep that was interrupted",
            found.run_dir.as_ref().map_or("RUN_DIR".to_string(), |d| d.display().to_string()),
            file.display()
        );
        return match &found.damage {
            None => Ok(()),
            Some(_) if found.unfinished => Err(Error::Other(format!(
                "{}: an unfinished frame file, of a backward sweep writing it now or of one interrupted; its {} complete frames can be analysed already, and {resume}",
                args.dir.display(),
                found.frames
            ))),
            Some(_) => {
                let options: Option<clv::stage::backward::BackwardOptions> = found.backward.clone().and_then(|b| serde_json::from_value(b).ok());
                let rewrite = clv::stage::backward::rewrite_advice(&args.dir, options.as_ref(), found.run_dir.as_deref());
                Err(Error::Other(format!("{}: damaged or cut short; its {} complete frames can still be analysed; {rewrite}", args.dir.display(), found.frames)))
            }
        };
    }
    let found = inspect::inspect(&args.dir)?;
    print_inspection(&found, found.text(), args.json)?;
    // Damaged segments and gaps are repaired by a forward resume; each damaged record's line,
    // and a run.json that disagrees with the segments, says what repairs it.
    let only_records = found.segments.iter().all(|s| s.damage.is_none()) && found.gaps.is_empty();
    // With --json, what the text calls DAMAGE lines are the object's fields.
    let (lines, above) = if args.json { ("damaged_records and meta_mismatch entry of the JSON", "in the JSON's segments and gaps") } else { ("DAMAGE line above", "above") };
    match (found.intact, only_records) {
        (true, _) => Ok(()),
        (false, true) => Err(Error::Other(format!("{}: damage found; each {lines} says how to repair it", args.dir.display()))),
        (false, false) => Err(Error::Other(format!("{}: damaged files found ({above}); repair them with `clv forward --resume {}`", args.dir.display(), args.dir.display()))),
    }
}

/// An inspection as one JSON object, or as its text.
fn print_inspection<T: serde::Serialize>(found: &T, text: String, json: bool) -> Result<()> {
    if json { print_json(found) } else { emit(&text) }
}
