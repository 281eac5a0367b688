//! The grasp autoencoder's maps decoded as `python -m train_ae.evaluate` decodes them, and the
//! grasps moved from the network's input pixels back to the crop's: one home for the `ae`
//! bridge's network source (`ae::grasps`, cargo feature `ae`) and for Python (`lgdm.sim.decode_grasps`), so
//! a grasp network wrapped as a Python callable gives the robot the same grasps, bit for bit.

use lgdm_pointcloud::grasp::decode::{DecodedGrasp, GraspDecodeParams, InputCrop};

/// The decoder parameters for at most `k` grasps (at least 1) with the jaw of a checkpoint
/// (`jaw_side_fraction`, `None`: half the opening); every other field is train_ae's default, as
/// `python -m train_ae.evaluate` decodes.
pub fn decode_params(jaw_side_fraction: Option<f32>, k: usize) -> GraspDecodeParams {
    GraspDecodeParams {
        num_grasps: k.max(1),
        jaw_side_fraction,
        ..GraspDecodeParams::default()
    }
}

/// A grasp decoded on the `input_px`-side maps, in the pixels of the `crop_px`-side crop they
/// were resized from: the centre pixel-centre aligned (`(x + ½)·s − ½`, the [`InputCrop`]
/// convention of the training resize), opening and jaw × `s`, angle and quality unchanged, with
/// `s = crop_px / input_px`.
pub fn crop_from_input(grasp: &DecodedGrasp, crop_px: usize, input_px: usize) -> DecodedGrasp {
    let s = crop_px as f32 / input_px as f32;
    let window = InputCrop {
        x0_px: 0.0,
        y0_px: 0.0,
        image_px_per_map_px: s,
    };
    DecodedGrasp {
        center_px: window.image_from_map(grasp.center_px),
        width_px: grasp.width_px * s,
        jaw_px: grasp.jaw_px * s,
        ..*grasp
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Input pixel 0 covers crop pixels 0 and 1 (centre 0.5); lengths double; the angle stays.
    #[test]
    fn input_grasps_map_to_crop_pixels_pixel_centre_aligned() {
        let g = DecodedGrasp {
            center_px: [0.0, 55.5],
            angle: 0.7,
            width_px: 20.0,
            jaw_px: 10.0,
            quality: 0.9,
        };
        let c = crop_from_input(&g, 224, 112);
        assert_eq!(c.center_px, [0.5, 111.5]);
        assert_eq!((c.width_px, c.jaw_px), (40.0, 20.0));
        assert_eq!((c.angle, c.quality), (0.7, 0.9));
        // At the crop's own size nothing moves.
        assert_eq!(crop_from_input(&g, 112, 112), g);
    }

    #[test]
    fn decode_params_carry_the_checkpoint_jaw_and_k() {
        let p = decode_params(Some(0.09), 3);
        assert_eq!((p.num_grasps, p.jaw_side_fraction), (3, Some(0.09)));
        assert_eq!(
            p.quality_threshold,
            GraspDecodeParams::default().quality_threshold
        );
        assert_eq!(decode_params(None, 0).num_grasps, 1);
    }
}
