"""Calibration of the cameras (thesis 3.3-3.6, section 8.2, Appendix A steps 2-3).

The thesis clicked the board corners by hand in Bouguet's MATLAB toolbox,
calibrated each camera (Tables 8.1-8.3), then each of the three pairs
(Table 8.4), and checked distances on the grid (Table 8.5). Here all of it is
automatic:

- :mod:`.board`: checkerboard detection with sub-pixel refinement;
- :mod:`.bundle`: one camera's intrinsics with 3-sigma uncertainties, and the
  bundle adjustment of a pair (stereo) or of all cameras (joint rig);
- :mod:`.rig`: :func:`calibrate_rig` (pairwise as the thesis, or joint) and
  the comparison of the two;
- :mod:`.bouguet`: import of the toolbox's ``Calib_Results*.mat``;
- :mod:`.check`: the grid-distance check of section 8.3 (Table 8.5);
- :mod:`.report`: the tables and the ``horsemocap calibrate`` command.

``rig.toml`` is read and written by :func:`horsemocap.camera.read_rig` and
:func:`horsemocap.camera.write_rig` (re-exported here).
"""
from ..camera import read_rig, rig_to_toml, write_rig
from .board import (MAX_GRID_IRREGULARITY, BoardViews, CalibrationError, board_points, canonical_order,
                    detect_board, detect_views, grid_irregularity, parse_board, square_size_px,
                    subpix_window, view_keys, views_from_corners)
from .bouguet import (BouguetSingle, BouguetStereo, load_bouguet_single, load_bouguet_stereo,
                      rig_from_bouguet_pairs, rig_from_bouguet_stereo)
from .bundle import (INTRINSIC_NAMES, BundleResult, IntrinsicResult, bundle_adjust, calibrate_camera,
                     flip_view, harmonize_views)
from .check import GridCheck, grid_distance_check, triangulate
from .report import calibrate_command, format_calibration_tables, format_comparison, format_per_view_errors
from .rig import (RigCalibration, RigComparison, align_views, calibrate_rig, compare_rigs, pair_closure,
                  rig_from_pairs, pair_rig, pairwise_rig)

__all__ = [n for n in dir() if not n.startswith("_")]
