"""Robot-side use of an sgjax actor exported as ONNX (``python -m train.export RUN --format
onnx``): ROS 2 messages to the policy's observation (:mod:`.observation`), the ONNX actor
(:mod:`.actor`), its actions to velocity commands (:mod:`.commands`) and an ``rclpy`` node
around them (:mod:`.node`). Needs numpy and onnxruntime only; nothing of JAX, sgjax or the
trainer. The message handling works on any object with the ROS 2 field names: ``rclpy``'s
messages on a robot, ``rosbags``' typestore messages in the tests and in bag replays."""
