"""Run-time support of the generated ROS 2 nodes. These modules are copied into each
generated workspace (package ``<system>_runtime``) and need rclpy; rssmc never imports them.
They import each other relatively only."""
