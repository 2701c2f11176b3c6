//! Locating a key in a TOML text takes any text, any key path and any offset — a mistake's
//! place is computed from what a hostile file holds — and never panics: the place found is
//! inside the text, or there is none.

use proptest::prelude::*;
use truepos_files::toml_place::{key_on_line, place, span, steps};

proptest! {
    #[test]
    fn any_text_and_key_path_give_a_place_inside_the_text_or_none(
        text in "(\\PC|\n|\\[|\\]|=|\"|\\.){0,200}",
        key in "(\\PC|\\[|\\]|\\.|[0-9]){0,40}",
        offset in 0usize..400,
    ) {
        let path = steps(&key);
        if let Some(s) = span(&text, &path) {
            prop_assert!(s.start <= text.len());
        }
        if let Some((line, column)) = place(&text, &path) {
            prop_assert!(line >= 1 && column >= 1 && line <= text.lines().count().max(1));
        }
        let k = key_on_line(&text, offset);
        prop_assert!(k.len() <= text.len());
    }

    #[test]
    fn a_key_written_in_a_table_is_found_on_its_line(
        table in "[a-z]{1,8}", key in "[a-z]{1,8}", pad in 0usize..5,
    ) {
        let text = format!("{}[{table}]\n{key} = 1\n", "\n".repeat(pad));
        let path = format!("{table}.{key}");
        prop_assert_eq!(place(&text, &steps(&path)), Some((pad + 2, 1)));
    }
}
