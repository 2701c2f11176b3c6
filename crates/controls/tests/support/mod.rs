//! What the table tests share: a one-character corruption of a valid file, for the
//! "never panics" properties.

/// `text` with the character at `at` (modulo its length) replaced by `with`, or deleted.
pub fn mutate(text: &str, at: usize, with: char, delete: bool) -> String {
    let mut chars: Vec<char> = text.chars().collect();
    let i = at % chars.len();
    if delete {
        chars.remove(i);
    } else {
        chars[i] = with;
    }
    chars.into_iter().collect()
}
