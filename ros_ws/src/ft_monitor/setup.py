from setuptools import find_packages, setup

package_name = "ft_monitor"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},  # colcon test runs test/ with pytest
    zip_safe=False,
    maintainer="ft-arms maintainers",
    maintainer_email="maintainers@ft-arms.org",
    description="Locked-joint detection and reduced-Jacobian command remapping node.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "monitor_node = ft_monitor.monitor_node:main",
        ],
    },
)
