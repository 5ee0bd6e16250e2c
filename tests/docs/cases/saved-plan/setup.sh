# The plan a reviewer saw, then an edit to the env script after it.
fogiac plan --out plan.json > /dev/null
printf 'export PLANNER_THREADS=16\n' > ws/setup.sh
