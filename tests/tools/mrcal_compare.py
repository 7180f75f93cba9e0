#!/usr/bin/python3
# Compares a clearfit .cameramodel with one written by mrcal-calibrate-cameras,
# using mrcal's own Python (run with /usr/bin/python3). Prints one JSON object:
#   ours:    lensmodel, intrinsics, imagersize as mrcal.cameramodel reads them
#   mrcal:   intrinsics, rms_px (inlier corners, per coordinate), outliers,
#            missing (corners given as missing)
#   diff_px: mrcal.projection_diff(ours, mrcal) at the gx x gy nodes of
#            mrcal.sample_imager (row-major, edge to edge: node i of n at
#            i (W-1)/(n-1), the image corners included), implied rotation
#            fitted by mrcal, no uncertainty weighting
#   uncertainty_px: mrcal.projection_uncertainty of mrcal's model,
#            worst-direction stdev, at the same nodes, points at --distance,
#            with --sigma as the observed pixel uncertainty
#   uncertainty_ours_px (with --solution S.json {intrinsics, frames (rt
#            cam_from_board per view), warp, weights (per corner, < 0 unused)}):
#            the same, computed by mrcal's Python on OUR problem at OUR solution
#            (mrcal's optimization_inputs with our state and weights swapped in);
#            --solution-weight-scale c: our final solve multiplied the weights
#            by c (mrcal's regularisation scaled to the corners' noise), so the
#            weights and --sigma are multiplied by c for this one
import argparse, json, sys
import numpy as np
import mrcal

p = argparse.ArgumentParser()
p.add_argument('--ours', required=True)
p.add_argument('--mrcal', required=True)
p.add_argument('--grid', type=int, nargs=2, default=(17, 13))
p.add_argument('--distance', type=float, required=True)
p.add_argument('--sigma', type=float, required=True)
p.add_argument('--solution')
p.add_argument('--solution-weight-scale', type=float, default=1.0)
a = p.parse_args()

ours = mrcal.cameramodel(a.ours)
ref = mrcal.cameramodel(a.mrcal)
gx, gy = a.grid
W, H = ref.imagersize()

oi = ref.optimization_inputs()
x = mrcal.optimizer_callback(**oi)[1]
nb = mrcal.num_measurements_boards(**oi)
obs = oi['observations_board']
inlier = obs[..., 2].ravel() >= 0
xb = x[:nb].reshape(-1, 2)[inlier]
rms = float(np.sqrt(np.mean(xb * xb)))

diff = mrcal.projection_diff((ours, ref), gridn_width=gx, gridn_height=gy, use_uncertainties=False)[0]

q = mrcal.sample_imager(gx, gy, W, H).reshape(-1, 2)  # the nodes projection_diff uses

def uncertainty(model, sigma=a.sigma):
    v = mrcal.unproject(q, *model.intrinsics(), normalize=True)
    return np.asarray(mrcal.projection_uncertainty(v * a.distance, model=model, what='worstdirection-stdev',
                                                   observed_pixel_uncertainty=sigma)).ravel().tolist()

out_extra = {}
if a.solution:
    sol = json.load(open(a.solution))
    oi2 = dict(oi)
    oi2['intrinsics'] = np.array([sol['intrinsics']], dtype=float)
    oi2['frames_rt_toref'] = np.array(sol['frames'], dtype=float)
    oi2['calobject_warp'] = np.array(sol['warp'], dtype=float)
    obs2 = obs.copy()
    w = np.array(sol['weights'], dtype=float).reshape(obs.shape[:-1])
    obs2[..., 2] = np.where(w > 0, w * a.solution_weight_scale, w)
    oi2['observations_board'] = obs2
    oi2['do_apply_outlier_rejection'] = False
    out_extra['uncertainty_ours_px'] = uncertainty(mrcal.cameramodel(optimization_inputs=oi2, icam_intrinsics=0),
                                                   a.sigma * a.solution_weight_scale)

json.dump({**out_extra,'ours': {'lensmodel': ours.intrinsics()[0], 'intrinsics': ours.intrinsics()[1].tolist(),
                    'imagersize': [int(s) for s in ours.imagersize()]},
           'mrcal': {'intrinsics': ref.intrinsics()[1].tolist(), 'rms_px': rms,
                     'inliers': int(np.count_nonzero(inlier)), 'corners': int(inlier.size)},
           'diff_px': np.asarray(diff).ravel().tolist(),
           'uncertainty_px': uncertainty(ref)}, sys.stdout)
