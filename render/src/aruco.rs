//! ArUco fiducials: OpenCV's `DICT_4X4_50` as cell patterns for [`crate::Marker`].

/// The 50 markers of OpenCV's `DICT_4X4_50`: the first 50 entries of `DICT_4X4_1000_BYTES`
/// in OpenCV's `modules/objdetect/src/aruco/predefined_dictionaries.hpp`, rotation 0 only
/// (OpenCV stores all four rotations for matching; a renderer needs one). Two bytes per
/// marker: the 16 inner bits row-major, most significant bit first, 1 = white.
#[rustfmt::skip]
const DICT_4X4_50: [[u8; 2]; 50] = [
    [181, 50], [15, 154], [51, 45], [153, 70], [84, 158], [121, 205], [158, 46], [196, 242], [254, 218], [207, 86],
    [249, 145], [17, 167], [14, 183], [42, 15], [36, 177], [38, 62], [70, 101], [102, 0], [108, 94], [118, 175],
    [134, 139], [176, 43], [204, 213], [221, 130], [254, 71], [148, 113], [172, 228], [165, 84], [33, 35], [52, 111],
    [68, 21], [87, 178], [158, 207], [240, 203], [8, 174], [9, 41], [24, 117], [4, 255], [13, 246], [28, 90],
    [23, 24], [42, 40], [50, 140], [56, 178], [36, 232], [46, 235], [45, 63], [75, 100], [80, 46], [80, 19],
];

/// The cells of marker `id` (0..=49) of OpenCV's `DICT_4X4_50`: 6 x 6, row-major, `true` =
/// white, the one-cell black border included, as `cv2.aruco.generateImageMarker` draws it
/// (row 0 at the top of the printed marker). `None` for an id outside the dictionary.
pub fn aruco_4x4_50(id: usize) -> Option<Vec<bool>> {
    let [hi, lo] = *DICT_4X4_50.get(id)?;
    let bits = u16::from_be_bytes([hi, lo]);
    let mut cells = vec![false; 36];
    for r in 0..4 {
        for c in 0..4 {
            cells[(r + 1) * 6 + c + 1] = bits & (1 << (15 - (r * 4 + c))) != 0;
        }
    }
    Some(cells)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marker_zero_has_opencvs_first_row_and_a_black_border() {
        let cells = aruco_4x4_50(0).expect("id 0");
        // 181 = 0b1011_0101: the inner rows 1011 and 0101.
        let row = |r: usize| cells[r * 6..r * 6 + 6].to_vec();
        assert_eq!(row(1), [false, true, false, true, true, false]);
        assert_eq!(row(2), [false, false, true, false, true, false]);
        assert!(row(0).iter().chain(&row(5)).all(|&c| !c));
        assert!((0..6).all(|r| !cells[r * 6] && !cells[r * 6 + 5]));
    }

    #[test]
    fn ids_past_the_dictionary_are_refused() {
        assert!(aruco_4x4_50(49).is_some());
        assert!(aruco_4x4_50(50).is_none());
    }
}
