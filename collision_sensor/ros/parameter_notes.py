"""What the parameter reference says beyond each parameter's declaration.

The node's parameters are declared once, in :data:`collision_sensor.ros.node_parameters.PARAMETERS`
(name, typed default, description, valid values, settable at run time).
``scripts/parameter_reference.py`` writes ``config/collision_sensor.yaml`` and
``docs/parameters.md`` from that table, grouped by :data:`SECTIONS`, each parameter's
description followed by its :data:`DETAILS` (``test/test_parameter_reference.py`` fails when
either file is stale, or when a name here is no parameter). A parameter with no entry here is
listed with its description alone, in the section of the parameter before it.
"""

#: ``{first parameter of a section: the section's title}``, in the table's order.
SECTIONS = {
    'urdf_path': 'the robot',
    'allowed_collisions': 'which pairs are checked',
    'motion_tolerance': 'the engine (same answers whatever the choice; only the speed changes)',
    'padding': 'padding',
    'require_all_joints': 'joint states',
    'on_rejected_input': 'fail safe: the node never goes quiet on "clear"',
    'warning_distance': 'output',
    'scene_max_objects': 'the scene topic (visualization_msgs/MarkerArray on "scene", '
                         'docs/dynamic_scene.md)',
    'max_trajectory_bytes': 'planned trajectories (trajectory -> trajectory_result, '
                            'trajectory_out)',
    'point_cloud_topics': 'point clouds (sensor_msgs/PointCloud2, docs/point_clouds.md)',
}

#: ``{parameter: what the reference says after its description}``.
DETAILS = {
    'urdf_path':
        'As robot_state_publisher publishes it. A new description replaces the model once it '
        'has loaded; a bad one is rejected and logged.',
    'xacro_args':
        'Expanded with the xacro package.',
    'srdf_path':
        'It applies to a robot from robot_description too, so it must match it.',
    'package_paths':
        'E.g. ["example-robot-data=/opt/erd/share/example-robot-data"]. Tried first; then the '
        "ament index, then the URDF's directory and its ancestors.",
    'allowed_collisions':
        'A name that is neither a link nor a scene object is kept for an object of that name '
        'still to come on the scene topic: the log names it with the closest link (a typo shows), '
        '/diagnostics lists it (names_pending) until the object arrives.',
    'ignore_adjacent':
        'A link is paired with its nearest ancestor that has geometry, across links without any.',
    'motion_tolerance':
        '0 is exact: any change re-checks the pairs it affects.',
    'expansion':
        '"larger" compares volumes, "wider" half diagonals.',
    'obb_fit':
        '"refined": principal axes, then the tightest rectangle around each; "min_volume" is '
        'slow.',
    'mesh_containment':
        'It costs a ray test per element pair near each other.',
    'padding':
        'Scene objects are never padded; distances shrink by the sum of the paddings. A change at '
        'run time builds a new checker while the current one answers.',
    'link_padding':
        'E.g. ["panda_hand=0.02", "panda_link0=0.0"]; an unknown link stops the node at start-up.',
    'require_all_joints':
        'Joints not heard would be checked at 0 (false: check at once, unheard joints at 0). The '
        'variables of planar and floating joints (a mobile or floating base, an SRDF virtual '
        'joint: x, y, theta, trans_*, rot_*) are never waited for: they start at the world origin '
        'until a joint state names them.',
    'stale_timeout':
        'A driver publishes joint states continuously, even at rest; for a publisher that stops '
        'when the robot stops, raise it, or set stale_policy: hold.',
    'joint_limit_policy':
        'A rejected message leaves the state unchanged, and a throttled warning names the joint, '
        'the value and the limits. NaN and inf are always rejected.',
    'joint_limit_tolerance':
        'Above encoder noise and calibration offsets, far below unit or joint-order errors.',
    'max_unknown_joints':
        'At most 10 of them are shown on /diagnostics.',
    'max_joint_state_bytes':
        'So a publisher cannot make the node decode huge name lists.',
    'joint_states_qos':
        '"sensor_data" drops old states under load, as drivers publish them; with "reliable" the '
        'publisher must be reliable too.',
    'overload_policy':
        '"every" suits a recording replayed with collision_sensor_play --as-fast-as-possible.',
    'check_motion':
        'Certified, not sampled (docs/motion.md). An engine error or a new robot also starts a '
        'new motion (/diagnostics: motion, new_motions_*). A stream of jumps (random '
        "configurations) costs much more per verdict than a driver's stream of small steps "
        '(docs/performance.md): turn it off there.',
    'on_rejected_input':
        'Each of on_rejected_input, on_engine_error and stale_policy is "contact" (contact true '
        'with a colliding_pairs entry naming the reason: the node does not know the robot is '
        'clear, so it does not say so) or "hold" (contact repeats the verdict of the last state '
        'checked, the entry first on colliding_pairs). A failure entry has no ":" in its name '
        '(joint_state_rejected, waiting_for_joints, engine_error, joint_states_stale), level '
        'ERROR, values kind, reason and policy. With no state checked yet, "hold" has nothing to '
        'hold and answers as "contact". Every joint state is answered.',
    'on_engine_error':
        'The merge is undone; the next state is checked from scratch.',
    'stale_policy':
        '"contact" publishes once per stale episode.',
    'warning_distance':
        'near is std_msgs/Bool; min_distance std_msgs/Float64, the smallest padded distance of a '
        'pair nearer than this (<= 0 in contact, .inf when none is); near_pairs a '
        'diagnostic_msgs/DiagnosticArray, one status per such pair with its distance and nearest '
        'points. E.g. 0.05 warns 5 cm before contact.',
    'warning_ignore':
        'E.g. the UR5\'s ["ee_link:wrist_2_link"], about 2 cm apart in every configuration. Names '
        'as in allowed_collisions (an object still to come too).',
    'publish_markers':
        "Frame: the robot's root link. Colliding links' boxes (grown by their padding) are red "
        'CUBE markers; scene objects grey (world), green (attached) or red (colliding); with a '
        'warning_distance, nearest points are joined by orange lines (LINE_LIST), contact points '
        'are red spheres (SPHERE_LIST) and each distance is text. At most 10 Hz while the same '
        'pairs last, and when the scene changes.',
    'scene_max_triangles':
        'A TRIANGLE_LIST or a MESH_RESOURCE.',
    'scene_max_total_triangles':
        'About 450 bytes each.',
    'max_trajectory_bytes':
        "The answer's kind is oversized.",
    'point_cloud_topics':
        'E.g. ["camera/depth/points"]. header.frame_id must be a link of the URDF or the world '
        'frame (no tf2).',
}
