//! What each study's summary says about its differences from the paper:
//! findings of the investigation, written once and printed with every run.

use crate::spec::StudyName;

/// Notes for the summary of `study` (Markdown, may be empty).
pub fn notes(study: StudyName) -> &'static str {
    match study {
        _ => "",
    }
}
