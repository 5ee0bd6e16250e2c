# The import guide's launch file with a typo in the dexnet node's machine type.
cp -r "$REPO/tests/docs/cases/fogros-robot/." .
sed -i 's/g4dn.xlarge/g4dn.xlrge/' src/bringup/launch/robot.launch
