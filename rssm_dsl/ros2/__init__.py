"""The ROS 2 backend (`rssmc ros2`, docs/ros2.md): a colcon workspace whose nodes run the
specification's behaviours on ROS 2 with the four communication modes kept.

Modules: names (checks, E860), pycode (expressions and statements to Python), msgtypes
(message types), stdtypes (standard messages of the data topics, the <spec>.ros2.toml
types file: E862, E863), nodecode (the code of one node), evaluate (values known at generation
time), shipping (modules of bindings), viewmodel, generator (templates/*.j2), launch_runner
(runs generated launch files without the ROS launch system), toolchain (ROS 2 from PyPI
wheels: venv, colcon), record (a ROS node recording a tracking experiment's topics), tracking
(its figures, as `rssmc run` computes them) and simrun (the LWR4+ experiment on a built
workspace). runtime/ is the support library copied into every workspace; it needs rclpy and
is never imported by rssmc itself (record imports its channels.digest, in the ROS venv).
"""
