"""Acceptance evidence: one run's report directory as a package that names what was tested and shows
whether it was changed since.

* :mod:`.manifest`: ``manifest.json``, every file of the package with its SHA-256 and size, and the check
  ``isight-conformance verify`` runs;
* :mod:`.signatures`: OpenSSH signatures of the manifest (``ssh-keygen -Y sign`` / ``-Y verify``), one file per
  signer under ``signatures/``;
* :mod:`.dut`: the device under test (``--dut``, ``--dut-file``) and who ran the test;
* :mod:`.tester`: the test system's identity (suite version and commit, Python, OS, libraries, PROTOCOL.md);
* :mod:`.declaration`: the vendor's declaration (``--declared``), its profile, and the declared / observed table;
* :mod:`.record`: what a run hands its reports (run ID, DUT, tester, declaration).
"""
