"""lomanip_perception: prompts and RGB-D to 3D contacts per subtask (paper Sec. III-A1, III-A2).

Core modules (no rclpy): prompts (paper's prompt template, subtask parser), roles + registry (the six
model roles and their backends), synthetic (offline 'synthetic' demonstrations and stand-ins),
scene (object primitives, surface projection), geometry + transfer (geometry-aware contact transfer
and the geometry-unaware ablation), pipeline, evaluation, config. ROS: conversions, perception_node.
"""
