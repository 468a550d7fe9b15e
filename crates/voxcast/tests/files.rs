//! The input log of a one-command process (`files::record_inputs`, as the
//! CLI runs): every file a reader opened is an input no output may replace.
//! A test binary of its own, since the log is process-wide.

use std::io::Write;
use voxcast::files::{self, Outputs};

#[test]
fn files_read_are_inputs_under_any_name_and_are_never_written() {
    files::record_inputs();
    let dir = tempfile::tempdir().unwrap();
    let hdr = dir.path().join("v.nhdr");
    let raw = dir.path().join("v_data.raw");
    std::fs::write(&hdr, "NRRD0004\n").unwrap();
    std::fs::write(&raw, "precious").unwrap();
    let input = hdr.to_string_lossy().into_owned();
    let mut o = Outputs::new([&input]);
    let e = o.plan("-o", &hdr, &[]).unwrap_err().to_string();
    assert!(e.contains("refusing"), "{e}");
    // The data file is refused once the reader has opened it.
    o.plan("--stats-json", &raw, &[]).unwrap();
    assert!(!files::was_read(&raw));
    files::read_bytes(&raw, 100).unwrap();
    assert!(files::was_read(&raw));
    assert!(files::was_read(&dir.path().join(".").join("v_data.raw")));
    let e = o.check().unwrap_err().to_string();
    assert!(
        e.contains("--stats-json") && e.contains("reads as input"),
        "{e}"
    );
    assert!(o.write(&raw, |w| w.write_all(b"gone")).is_err());
    drop(o);
    assert_eq!(std::fs::read(&raw).unwrap(), b"precious");
    // A hard link is the same file.
    let link = dir.path().join("hard");
    std::fs::hard_link(&raw, &link).unwrap();
    assert!(files::was_read(&link));
    assert!(files::write_file(&link, |w| w.write_all(b"gone")).is_err());
    assert_eq!(std::fs::read(&raw).unwrap(), b"precious");
    // Another file of the same folder is not an input.
    let other = dir.path().join("other.txt");
    std::fs::write(&other, "x").unwrap();
    assert!(!files::was_read(&other));
}
