"""Recordings made elsewhere into trial archives: ROS 2 bags, folders of WAV + CSV + video, other
rigs' trial folders, and manifests that list many of them (docs/data.md).

    streams        a recording's microphones as read, before alignment; the import's one-line error
    trial_files    the files of a trial folder: WAV, joints CSV, camera video or images, reference
    alignment      the recorder's rule applied after the fact: one step per frame, clocks, gaps
    hand_folder    a trial folder of the hand's layout
    rig_folder     a rig file (TOML) and a trial folder of its layout
    ros_messages   the ROS 2 message types a bag may hold and their decoding
    ros_bag        a ROS 2 bag read into timestamped streams and aligned
    mapping_file   the TOML files: a bag's mapping and a trial's fields
    manifest_file  the manifest CSV, its label map and split rules
    batch          every trial of a manifest imported as one transaction, then indexed
    example_rig    placeholder recordings of a rig unlike the hand, and the import's benchmark

The hand's own recorder is not here: it lives in `acquisition/` with the devices it drives, and
both write archives through `fabricjax.store.archive` and read Minsight's force the same way
(`fabricjax.force_proxy`).
"""
