import sys

from tactile_viz.assetgen.build import main

sys.exit(main())
