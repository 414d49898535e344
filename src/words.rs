//! Counts in words for summary lines: "1 frame", "2 frames", "1 mesh".

/// `n` and `word`, plural unless `n` is 1 (`-es` after s, sh, ch and x).
pub fn plural(n: usize, word: &str) -> String {
    if n == 1 {
        return format!("1 {word}");
    }
    if let Some(stem) = word.strip_suffix("vertex") {
        return format!("{n} {stem}vertices");
    }
    let es = ["s", "sh", "ch", "x"].iter().any(|e| word.ends_with(e));
    format!("{n} {word}{}", if es { "es" } else { "s" })
}

/// The first five `items` joined with commas, and how many more: "a, b,
/// c, d, e and 7 more".
pub fn at_most_five(items: impl ExactSizeIterator<Item = String>) -> String {
    let n = items.len();
    let shown: Vec<String> = items.take(5).collect();
    match n {
        0..=5 => shown.join(", "),
        n => format!("{} and {} more", shown.join(", "), n - 5),
    }
}

/// A prim by its type name, for messages: "a Mesh prim", or "an untyped
/// prim" for "".
pub fn prim_of_type(ty: &str) -> String {
    if ty.is_empty() {
        "an untyped prim".to_string()
    } else {
        format!("a {ty} prim")
    }
}

#[cfg(test)]
mod tests {
    use super::{plural, prim_of_type};

    #[test]
    fn prims_by_type() {
        assert_eq!(prim_of_type("Mesh"), "a Mesh prim");
        assert_eq!(prim_of_type(""), "an untyped prim");
    }

    #[test]
    fn singular_and_plural() {
        assert_eq!(plural(1, "frame"), "1 frame");
        assert_eq!(plural(0, "frame"), "0 frames");
        assert_eq!(plural(2, "mesh"), "2 meshes");
        assert_eq!(plural(3, "view-dependent mesh"), "3 view-dependent meshes");
        assert_eq!(plural(1, "curves prim"), "1 curves prim");
        assert_eq!(plural(2, "proxy vertex"), "2 proxy vertices");
    }
}
