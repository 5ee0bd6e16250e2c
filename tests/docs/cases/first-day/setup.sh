# The getting-started page's first line.
fogiac init --name first-day
