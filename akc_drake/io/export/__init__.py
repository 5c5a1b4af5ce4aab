"""Files in standard formats for the pipeline's skeletons: CSV and TRC (:mod:`.table`), C3D (:mod:`.c3d`), ROS 2
MCAP bags (:mod:`.ros2bag`), and the ``poses.npz`` reader they start from (:mod:`.poses`). BVH is written by
:mod:`akc_drake.operator.bvh_export` (beside the BVH reader and writer it uses); the format dispatch,
``export_poses``, is :mod:`akc_drake.pipeline.export`.
"""
