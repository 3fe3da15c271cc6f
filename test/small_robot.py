"""A small robot of every joint type and primitive, and a scene for it: the tests in several
layers share them."""
import textwrap

SMALL_ROBOT = textwrap.dedent('''\
    <robot name="small">
      <link name="base">
        <collision><geometry><box size="0.4 0.4 0.1"/></geometry></collision>
      </link>
      <link name="upper">
        <collision><origin xyz="0 0 0.25"/>
          <geometry><cylinder radius="0.05" length="0.5"/></geometry></collision>
        <collision><origin xyz="0 0 0.5"/><geometry><sphere radius="0.08"/></geometry></collision>
      </link>
      <link name="lower">
        <collision><origin xyz="0 0 0.2"/>
          <geometry><box size="0.06 0.06 0.4"/></geometry></collision>
      </link>
      <link name="slider"/>
      <link name="tool">
        <collision><geometry><box size="0.1 0.02 0.15"/></geometry></collision>
      </link>
      <joint name="shoulder" type="revolute">
        <parent link="base"/><child link="upper"/><origin xyz="0 0 0.05" rpy="0 0 0"/>
        <axis xyz="0 1 0"/><limit lower="-2.5" upper="2.5" effort="1" velocity="1"/>
      </joint>
      <joint name="elbow" type="continuous">
        <parent link="upper"/><child link="lower"/><origin xyz="0 0 0.5" rpy="0 0 0"/>
        <axis xyz="0 1 0"/>
      </joint>
      <joint name="extend" type="prismatic">
        <parent link="lower"/><child link="slider"/><origin xyz="0 0 0.4" rpy="0 0 0"/>
        <axis xyz="0 0 1"/><limit lower="-0.3" upper="0.1" effort="1" velocity="1"/>
      </joint>
      <joint name="wrist" type="revolute">
        <parent link="slider"/><child link="tool"/><origin xyz="0 0 0" rpy="0 0.3 0"/>
        <axis xyz="1 0 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/>
      </joint>
    </robot>
    ''')

SMALL_SCENE = {'objects': [
    {'name': 'pillar', 'cylinder': {'radius': 0.08, 'length': 1.2},
     'pose': {'xyz': [0.45, 0.0, 0.6], 'rpy': [0.0, 0.0, 0.0]}},
    {'name': 'shelf', 'box': {'size': [0.3, 0.6, 0.03]},
     'pose': {'xyz': [-0.4, 0.1, 0.7], 'rpy': [0.2, 0.0, 0.4]}},
    {'name': 'ball', 'sphere': {'radius': 0.12},
     'pose': {'xyz': [0.0, 0.0, 1.25]}},
]}
