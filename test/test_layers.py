"""The package's layers, as docs/engine.md's architecture section draws them, by imports.

model (files in, a model out) <- engine (the checker and the compiled engine) <- sensor (the
sensor without ROS: inputs in, verdicts out) <- tools (the offline command-line tools) <- ros
(everything on the ROS graph) <- testing (the sensor in users' own tests: the node and a client
of it, through ros). A layer imports only from layers to its left and from the base modules
(``errors``, ``untrusted_text``); rclpy and the message packages are imported only in ``ros``
and ``testing``. The package never imports the benchmarks
(a folder of the source tree, not installed) nor their peers (python-fcl, pinocchio, coal: test
extras); test_packaging.py checks the same on an installed wheel.
"""
import ast
import pathlib

import collision_sensor

PACKAGE_DIR = pathlib.Path(collision_sensor.__file__).parent
ORDER = ('model', 'engine', 'sensor', 'tools', 'ros', 'testing')
#: The layers that talk to the ROS graph.
ROS_LAYERS = ('ros', 'testing')
#: Imported by the benchmarks and the tests only, never by the package.
NOT_IN_THE_PACKAGE = ('benchmarks', 'scripts', 'fcl', 'pinocchio', 'coal', 'hppfcl')
ROS_ONLY = ('rclpy', 'sensor_msgs', 'std_msgs', 'visualization_msgs', 'diagnostic_msgs',
            'geometry_msgs', 'builtin_interfaces', 'std_srvs', 'rosidl_runtime_py',
            'trajectory_msgs')


def layer_of(path: pathlib.Path) -> str:
    parts = path.relative_to(PACKAGE_DIR).parts
    return parts[0] if len(parts) > 1 else 'base'


def imported_modules(path: pathlib.Path):
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.lineno, node.module
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name


def rank(layer: str) -> int:
    return -1 if layer == 'base' else ORDER.index(layer)


def sources():
    return sorted(PACKAGE_DIR.rglob('*.py'))


def test_every_module_sits_in_a_layer():
    assert {layer_of(path) for path in sources()} == {'base', *ORDER}
    base = {path.name for path in sources() if layer_of(path) == 'base'}
    assert base == {'__init__.py', 'errors.py', 'untrusted_text.py'}


def test_layers_import_only_layers_below_them():
    upward = []
    for path in sources():
        if path == PACKAGE_DIR / '__init__.py':
            continue  # the public API re-exports the checker, lazily
        layer = layer_of(path)
        for line, module in imported_modules(path):
            parts = module.split('.')
            if parts[0] == 'collision_sensor' and len(parts) > 1 and parts[1] in ORDER \
                    and rank(parts[1]) > rank(layer):
                upward.append(f'{path.relative_to(PACKAGE_DIR)}:{line} imports {module}')
    assert upward == []


def test_only_the_ros_layers_import_ros():
    outside = [f'{path.relative_to(PACKAGE_DIR)}:{line} imports {module}'
               for path in sources() if layer_of(path) not in ROS_LAYERS
               for line, module in imported_modules(path) if module.split('.')[0] in ROS_ONLY]
    assert outside == []


def test_the_package_imports_no_benchmark_and_no_peer():
    found = [f'{path.relative_to(PACKAGE_DIR)}:{line} imports {module}'
             for path in sources() for line, module in imported_modules(path)
             if module.split('.')[0] in NOT_IN_THE_PACKAGE]
    assert found == []


def test_the_checks_above_see_imports_inside_functions(tmp_path):
    probe = tmp_path / 'probe.py'
    probe.write_text('def f():\n    import rclpy\n    from collision_sensor.ros import node\n')
    assert [module for _, module in imported_modules(probe)] == ['rclpy',
                                                                  'collision_sensor.ros']
