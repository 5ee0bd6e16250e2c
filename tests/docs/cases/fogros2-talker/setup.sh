# FogROS2's own talker example, as shipped (it names no topics).
cp "$REPO/tests/data/fogros2_examples/talker.aws.launch.py" .
