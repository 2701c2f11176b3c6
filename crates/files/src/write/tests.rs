//! One test per rule of the writer.

use super::*;
use crate::test_dir;
use std::os::unix::fs::{FileTypeExt, PermissionsExt};

fn leftovers(d: &Path) -> Vec<String> {
    std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect()
}

#[test]
fn a_regular_file_is_replaced_whole_keeping_its_permissions() {
    let d = test_dir("replace");
    let out = d.join("out.txt");
    std::fs::write(&out, "old").unwrap();
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o640)).unwrap();
    write_whole(&out, b"new", &[]).unwrap();
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "new");
    let mode = std::fs::metadata(&out).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o640);
    assert!(leftovers(&d).is_empty());
}

#[test]
fn a_symlink_is_refused_and_neither_it_nor_its_target_changes() {
    let d = test_dir("symlink");
    let victim = d.join("victim.txt");
    std::fs::write(&victim, "precious").unwrap();
    let out = d.join("out.txt");
    std::os::unix::fs::symlink(&victim, &out).unwrap();
    let e = write_whole(&out, b"new", &[]).unwrap_err();
    assert!(e.to_string().contains("is a symbolic link"), "{e}");
    assert!(std::fs::symlink_metadata(&out)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "precious");
    // A dangling link is refused too: writing would create the file it names.
    let dangling = d.join("dangling.txt");
    std::os::unix::fs::symlink(d.join("nowhere"), &dangling).unwrap();
    assert!(write_whole(&dangling, b"new", &[]).is_err());
    assert!(!d.join("nowhere").exists());
    assert!(leftovers(&d).is_empty());
}

#[test]
fn a_planted_link_at_the_old_temporary_name_is_never_followed() {
    let d = test_dir("planted");
    let victim = d.join("victim.txt");
    std::fs::write(&victim, "precious").unwrap();
    let out = d.join("out.txt");
    std::os::unix::fs::symlink(&victim, d.join("out.txt.partial")).unwrap();
    write_whole(&out, b"new", &[]).unwrap();
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "precious");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "new");
}

#[test]
fn a_fifo_is_refused_without_blocking() {
    let d = test_dir("fifo");
    let out = d.join("out.txt");
    assert!(std::process::Command::new("mkfifo")
        .arg(&out)
        .status()
        .unwrap()
        .success());
    let e = write_whole(&out, b"new", &[]).unwrap_err();
    assert!(e.to_string().contains("is a FIFO"), "{e}");
    assert!(std::fs::symlink_metadata(&out)
        .unwrap()
        .file_type()
        .is_fifo());
}

#[test]
fn a_directory_is_refused() {
    let d = test_dir("dir");
    let out = d.join("sub");
    std::fs::create_dir(&out).unwrap();
    let e = write_whole(&out, b"new", &[]).unwrap_err();
    assert!(e.to_string().contains("is a directory"), "{e}");
    assert!(out.is_dir());
    assert!(leftovers(&d).is_empty());
}

/// A copy of `/dev/full` (character device 1:7) in a temporary directory: only root may
/// create one, so elsewhere the test says why it skips that case.
#[test]
fn a_device_node_is_refused_and_kept() {
    let d = test_dir("device");
    let out = d.join("full");
    let made = std::process::Command::new("mknod")
        .arg(&out)
        .args(["c", "1", "7"])
        .output()
        .unwrap();
    if !made.status.success() {
        eprintln!(
            "skipped: mknod needs root here ({}); the character device /dev/null is checked \
             instead",
            String::from_utf8_lossy(&made.stderr).trim()
        );
        let e = check_output(Path::new("/dev/null"), &[]).unwrap_err();
        assert!(e.to_string().contains("is a character device"), "{e}");
        return;
    }
    let e = write_whole(&out, b"new", &[]).unwrap_err();
    assert!(e.to_string().contains("is a character device"), "{e}");
    assert!(std::fs::symlink_metadata(&out)
        .unwrap()
        .file_type()
        .is_char_device());
    assert!(leftovers(&d).is_empty());
}

#[test]
fn an_input_is_refused_by_path_and_by_hard_link() {
    let d = test_dir("input");
    let input = d.join("model.toml");
    std::fs::write(&input, "model").unwrap();
    let e = write_whole(&input, b"new", &[("--model", &input)]).unwrap_err();
    assert!(
        e.to_string()
            .contains("is also this command's input --model"),
        "{e}"
    );
    let link = d.join("same.toml");
    std::fs::hard_link(&input, &link).unwrap();
    let spelled = d.join(".").join("model.toml");
    for out in [&link, &spelled] {
        assert!(write_whole(
            out,
            b"new",
            &[("--run", Path::new("x")), ("--model", &input)]
        )
        .is_err());
    }
    assert_eq!(std::fs::read_to_string(&input).unwrap(), "model");
}

#[test]
fn a_missing_directory_is_named() {
    let d = test_dir("missing");
    let out = d.join("no").join("out.txt");
    let e = write_whole(&out, b"new", &[]).unwrap_err();
    assert!(
        e.to_string()
            .contains(&format!("directory {}", d.join("no").display())),
        "{e}"
    );
}

#[test]
fn an_output_not_committed_leaves_the_old_file_and_no_temporary() {
    let d = test_dir("dropped");
    let out = d.join("out.txt");
    std::fs::write(&out, "old").unwrap();
    {
        let mut p = Pending::create(&out, &[]).unwrap();
        p.write_all(b"half").unwrap();
    }
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "old");
    assert!(leftovers(&d).is_empty());
}

#[test]
fn a_set_is_written_whole_or_not_at_all() {
    let d = test_dir("set");
    let (a, b) = (d.join("a.txt"), d.join("b.txt"));
    write_all_whole(&[(&a, b"one".as_slice()), (&b, b"two".as_slice())], &[]).unwrap();
    assert_eq!(std::fs::read_to_string(&a).unwrap(), "one");
    assert_eq!(std::fs::read_to_string(&b).unwrap(), "two");
    let (c, dir) = (d.join("c.txt"), d.join("sub"));
    std::fs::create_dir_all(&dir).unwrap();
    assert!(write_all_whole(&[(&c, b"1".as_slice()), (&dir, b"2".as_slice())], &[]).is_err());
    assert!(!c.exists());
    assert!(leftovers(&d).is_empty());
}

#[test]
fn a_stream_writes_into_a_character_device_and_refuses_the_rest() {
    let d = test_dir("stream");
    let input = d.join("run.csv");
    std::fs::write(&input, "time_s\n0\n").unwrap();
    let e = open_stream(&input, &[("--replay", &input)]).unwrap_err();
    assert!(
        e.to_string()
            .contains("is also this command's input --replay"),
        "{e}"
    );
    assert_eq!(std::fs::read_to_string(&input).unwrap(), "time_s\n0\n");
    let link = d.join("link.csv");
    std::os::unix::fs::symlink(&input, &link).unwrap();
    assert!(open_stream(&link, &[]).is_err());
    let fifo = d.join("fifo.csv");
    assert!(std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    assert!(open_stream(&fifo, &[]).is_err());
    assert!(open_stream(Path::new("/dev/null"), &[]).is_ok());
    let out = d.join("out.csv");
    std::fs::write(&out, "old content").unwrap();
    let mut f = open_stream(&out, &[]).unwrap();
    f.write_all(b"new").unwrap();
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "new");
}
